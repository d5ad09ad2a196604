"""Numerical PTRS imaging (Zhang, Tan & Ying 2019): the exact delay of eq. (1), the stationary
points of eq. (5) by Newton against a brute-force search, the tabulated phases, and the images
against back-projection; the stationary-point cache; bad input."""

from __future__ import annotations

import dataclasses
import functools
import warnings

import numpy as np
import pytest
import scipy.fft
from _line_scenes import compare_with_backprojection

import clsas
from clsas.image.ptrs import StationaryPoints, delay, ptrs_image, stationary_points
from clsas.image.ptrs.phase import compress_azimuth, decouple
from clsas.image.ptrs.stationary import delay_derivatives, hermite, legendre_phase, migration
from clsas.scene import presets
from clsas.scene.targets import PointTargets

V, C, F0 = 2.0, 1500.0, 150e3


def test_delay_is_zhang_eq1():
    t = np.linspace(-12.0, 12.0, 25)[:, None]
    r = np.array([43.0, 143.0, 204.0])[None, :]
    d = 0.61
    b = V * (V * t + d) + C * np.sqrt(V**2 * t**2 + r**2)
    eq1 = (b + np.sqrt(b**2 + (C**2 - V**2) * (2 * V * t * d + d**2))) / (C**2 - V**2)
    assert np.max(np.abs(delay(t, r, d, V, C) - eq1)) < 1e-15


def test_newton_stationary_points_match_brute_force():
    """Eq. (5) on a (f_tau, f_t) grid: Newton's points satisfy tau'(T) = -f_t / (f0 + f_tau) to
    1e-12 s, and a brute-force search (the zero of the phase's slope sampled every 0.2 ms over
    +-12 s, linearly interpolated) finds the same points to 1e-7 s."""
    ftau = np.linspace(-10e3, 10e3, 5)[:, None]
    ft = np.linspace(-50.0, 50.0, 7)[None, :]
    r, d = 143.0, 0.47
    s = -ft / (F0 + ftau)
    newton = stationary_points(s, r, d, V, C)
    _, d1, _ = delay_derivatives(newton, r, d, V, C)
    assert np.max(np.abs(d1 - s)) < 1e-14
    assert np.max(np.abs(stationary_points(s, r, d, V, C) - newton)) == 0.0  # deterministic
    grid = np.arange(-12.0, 12.0, 2e-4)
    tau = delay(grid, r, d, V, C)
    for k in np.ndindex(s.shape):
        phase = (F0 + ftau[k[0], 0]) * tau + ft[0, k[1]] * grid  # cycles, up to sign
        slope = np.diff(phase)
        i = int(np.flatnonzero(np.sign(slope[:-1]) != np.sign(slope[1:]))[0])
        mid = grid[:-1] + 1e-4
        brute = mid[i] - slope[i] * (mid[i + 1] - mid[i]) / (slope[i + 1] - slope[i])
        assert abs(brute - newton[k]) < 1e-7, (k, brute, newton[k])


def test_tabulated_phase_matches_newton():
    """The cache's Hermite tables give G (and so the PTRS phase) within 1e-6 rad of Newton."""
    offsets = np.array([0.03, 0.31, 0.59])
    points = StationaryPoints().bind(offsets, V, C, s_max=4e-4)
    t, g = points.tables([43.0, 204.0])
    s = np.random.default_rng(1).uniform(-4e-4, 4e-4, 200)
    _, exact = legendre_phase(s[None, None, :], np.array([43.0, 204.0])[None, :, None], offsets[:, None, None], V, C)
    err = 2 * np.pi * (F0 + 10e3) * np.abs(hermite(g, t, points.s_first, points.ds, s) - exact)
    assert err.max() < 1e-6
    # the migration m = tau(T(s)) - 2 r / c from the same interpolant (measured 1.5e-12 s)
    t_exact = stationary_points(s[None, None, :], np.array([43.0, 204.0])[None, :, None], offsets[:, None, None], V, C)
    m_exact = delay(t_exact, np.array([43.0, 204.0])[None, :, None], offsets[:, None, None], V, C) \
        - 2 * np.array([43.0, 204.0])[None, :, None] / C
    assert np.abs(migration(g, t, points.s_first, points.ds, s, np.array([43.0, 204.0]), C) - m_exact).max() < 2e-11
    assert points.solved == 2
    points.tables([204.0, 43.0])
    assert points.solved == 2


def test_phase_kernels_match_reference(opencl_device):
    """kernels/ptrs.cl against the float64 NumPy references on random data and the tables of a
    real geometry (a width that is no multiple of the kernels' 16 lanes): relative L2 below 7e-4
    (measured 7.4e-5: the float32 phases of the kernels, ~1e-5 cycle)."""
    rng = np.random.default_rng(7)
    points = StationaryPoints().bind([0.03, 0.31, 0.59], V, C, s_max=3.7e-4)
    t, g = points.tables([53.0, 143.0, *np.arange(40.0, 70.0, 0.5)])
    ft = np.fft.fftfreq(600, 0.01)
    ft = ft[np.abs(ft) <= 50.0]
    ftau = np.fft.fftfreq(777, 1 / 25e3)
    data = (rng.standard_normal((ft.size, ftau.size)) + 1j * rng.standard_normal((ft.size, ftau.size))).astype(np.complex64)
    r = np.linspace(40.0, 69.0, ftau.size)
    node = np.clip(np.floor((r - 40.0) / 0.5).astype(int), 0, 57)
    weight = (r - 40.0 - 0.5 * node) / 0.5
    results = {}
    for name in ("numpy", "opencl"):
        out = data.copy()
        decouple(out, ft, ftau, F0, g[1, 1] - g[1, 0], t[1, 1] - t[1, 0], points.s_first, points.ds, 2 * 90.0 / C,
                 backend=name)
        decouple(out, ft, ftau, F0, g[2, 0], t[2, 0], points.s_first, points.ds, 2 * 53.0 / C, backend=name)
        compress_azimuth(out, ft, F0, g[0, 2:], t[0, 2:], points.s_first, points.ds, node, weight, backend=name)
        results[name] = out
    err = np.linalg.norm(results["opencl"] - results["numpy"]) / np.linalg.norm(results["numpy"])
    assert err < 7e-4, err
    assert np.abs(np.abs(results["numpy"]) - np.abs(data)).max() < 1e-5  # phase only
    with pytest.raises(ValueError, match="slopes"):
        decouple(data.copy(), ft * 2, ftau, F0, g[0, 0], t[0, 0], points.s_first, points.ds, 0.0, backend="opencl")
    with pytest.raises(ValueError, match="complex64"):
        decouple(data.astype(np.complex128), ft, ftau, F0, g[0, 0], t[0, 0], points.s_first, points.ds, 0.0)


@functools.cache
def small_scene():
    """Zhang et al.'s sonar as the reproduction samples it (15 receivers on a 0.04 m pitch,
    PRI 0.15 s), three points at 44-58 m, omnidirectional elements (the processed band is cut
    to the transmitter's 4 pi / D, as back-projection's integration angle)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = presets.zhang2019(n_pulses=128, receivers=15, pri=0.15)
    pts = np.array([[50.0, 0.0, 0.0], [58.0, 1.5, 0.0], [44.0, -1.0, 0.0]])
    sc = sc.replace(targets=(PointTargets(pts),), array=dataclasses.replace(sc.array, tx_length=0.0, rx_length=0.0))
    return pts, clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


def test_eight_metre_sub_blocks_match_backprojection_and_reuse_stationary_points(opencl_device):
    """Uniform 8 m sub-blocks (points up to 4 m from their block's reference) with the residual
    range cell migration correction: every point where back-projection puts it (within 1/10 of
    a cell) with PSLR and ISLR within 1 dB of it (measured 0.2-0.41 dB); the stationary points
    of that run serve a second one unchanged (no range is solved again) and give the identical
    image."""
    pts, echo = small_scene()
    points = StationaryPoints()
    image = ptrs_image(echo, block_width=8.0, elements=(0.04, 0.02), deconvolve=False, points=points,
                       backend="opencl")
    assert len(image.provenance["blocks"]) == 4 and image.provenance["rcmc"]
    for row in compare_with_backprojection(image, echo, pts, 0.04):
        assert row["dy"] < 0.1 and row["dx"] < 0.1, row
        assert row["pslr"] < 1.0 and row["islr"] < 1.0, row
    solved = points.solved
    assert solved > 0 and image.provenance["stationary_points_solved"] == solved
    again = ptrs_image(echo, block_width=8.0, elements=(0.04, 0.02), deconvolve=False, points=points,
                       backend="opencl")
    assert points.solved == solved
    np.testing.assert_array_equal(again.data, image.data)


@pytest.mark.slow
def test_residual_rule_width(opencl_device):
    """The pi / 4 rule: 2.2 m sub-blocks for eq. (13) alone, which at 8 m leaves the point 4 m
    from its reference 3.7 dB (PSLR) and 4.7 dB (ISLR) off back-projection; with the residual
    migration correction the rule allows ~33 m (one block here) and every point stays within
    1 dB (measured 0.16-0.36 dB)."""
    pts, echo = small_scene()
    plain = ptrs_image(echo, elements=(0.04, 0.02), deconvolve=False, rcmc=False, backend="opencl")
    widths = {round(hi - lo, 1) for lo, hi, _ in plain.provenance["blocks"][1:-1]}
    assert max(widths) < 4.0
    for row in compare_with_backprojection(plain, echo, pts, 0.04):
        assert row["dy"] < 0.1 and row["dx"] < 0.1, row
        assert row["pslr"] < 1.5 and row["islr"] < 1.5, row
    eight = ptrs_image(echo, block_width=8.0, elements=(0.04, 0.02), deconvolve=False, rcmc=False, backend="opencl")
    worst = max(max(row["pslr"], row["islr"]) for row in compare_with_backprojection(eight, echo, pts, 0.04))
    assert worst > 3.0
    wide = ptrs_image(echo, elements=(0.04, 0.02), deconvolve=False, backend="opencl")
    assert len(wide.provenance["blocks"]) == 1
    for row in compare_with_backprojection(wide, echo, pts, 0.04):
        assert row["dy"] < 0.1 and row["dx"] < 0.1, row
        assert row["pslr"] < 1.0 and row["islr"] < 1.0, row


def test_bad_input(opencl_device):
    _, echo = small_scene()
    for width in (0.0, -2.0, np.nan):
        with pytest.raises(ValueError, match="block_width"):
            ptrs_image(echo, block_width=width)
    with pytest.raises(ValueError, match="reference_ranges"):
        ptrs_image(echo, reference_ranges=[-5.0])
    with pytest.raises(ValueError, match="range-compressed"):
        ptrs_image(echo.replace(compressed=False))
    with pytest.raises(TypeError, match="points"):
        ptrs_image(echo, points="cache")
    with pytest.raises(ValueError, match="another geometry"):
        ptrs_image(echo, points=StationaryPoints().bind([0.1], V, C, 1e-4))
    with pytest.raises(ValueError, match="straight"):
        bent = echo.tx_pos.copy()
        bent[:, 0] += 0.01 * np.sin(np.arange(echo.n_pulses))
        ptrs_image(echo.replace(tx_pos=bent))
    with pytest.raises(ValueError, match="uniform"):
        ptrs_image(echo, receivers=list(range(10)))  # a part of the array leaves gaps between pings
    with pytest.raises(ValueError, match="track line"):
        ptrs_image(echo.replace(rx_pos=echo.rx_pos + np.array([0.0, 0.0, 0.3])))
    for value, error in ((-1.0, ValueError), (np.nan, ValueError), (1e30, ValueError), ("far", TypeError)):
        for backend in ("numpy", "opencl"):
            with pytest.raises(error, match="reference_range"):
                clsas.pca_record(echo, reference_range=value, backend=backend)
    with pytest.raises(TypeError, match="rcmc"):
        ptrs_image(echo, rcmc="yes")


def test_hardening_regressions(opencl_device):
    """Issue #27's reproducers: a huge block width was a Newton RuntimeError (now refused by
    name; a width wider than the swath is one block referred to its middle); deconvolve="no"
    was read as True; the budget was checked only after allocating (now before the spectra,
    naming the sizes); samples of 3e38 returned inf (now refused before any FFT)."""
    _, echo = small_scene()
    with pytest.raises(ValueError, match="ptrs_image block_width"):
        ptrs_image(echo, block_width=1e300)
    one = ptrs_image(echo, block_width=1e6, rcmc=False)
    (lo, hi, ref), = one.provenance["blocks"]
    assert ref == pytest.approx((lo + hi) / 2)
    with pytest.raises(ValueError, match=r"reference_ranges\[1\]: must be in \[.*\] m \(ranges the record holds\)"):
        ptrs_image(echo, reference_ranges=[50.0, 5e5])
    for name in ("deconvolve", "rcmc"):
        with pytest.raises(TypeError, match=f"ptrs_image {name}: must be True or False"):
            ptrs_image(echo, **{name: "no"})
    for name, value, error in (("depth", "a", TypeError), ("workers", 0, ValueError), ("window", "box", ValueError),
                               ("block_width", "a", TypeError), ("interp", "cubic", ValueError),
                               ("tap_window", "hann", ValueError), ("workers", 1.5, TypeError)):
        with pytest.raises(error, match=f"ptrs_image {name}"):
            ptrs_image(echo, **{name: value})
    import tracemalloc

    with clsas.use_memory_budget("2M"):
        tracemalloc.start()
        with pytest.raises(clsas.errors.MemoryBudgetError, match="ptrs_image of 15 receivers"):
            ptrs_image(echo)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert peak < 8 * 2**20, peak  # refused before its arrays (91 MiB) were allocated
    loud = echo.replace(data=(echo.data * np.float32(3e38 / np.abs(echo.data).max())).astype(np.complex64))
    for backend in ("numpy", "opencl"):
        with pytest.raises(ValueError, match="ptrs_image echo.data: samples up to .*e\\+38 would overflow complex64"):
            ptrs_image(loud, backend=backend)


def test_strip_template_signature(opencl_device):
    """ptrs_image takes the strip-map template's keyword-only options with its defaults
    (clsas.image.strip.strip_job) where it shares them; ``interp`` and ``tap_window`` are the
    residual migration correction's, recorded in the provenance."""
    import inspect

    from clsas.image.strip import strip_job

    ours, template = inspect.signature(ptrs_image).parameters, inspect.signature(strip_job).parameters
    shared = ("elements", "deconvolve", "window", "interp", "tap_window", "depth", "workers", "backend")
    for name in shared:
        assert ours[name].kind is inspect.Parameter.KEYWORD_ONLY and ours[name].default == template[name].default, name
    assert [p.name for p in ours.values() if p.kind is not inspect.Parameter.KEYWORD_ONLY] == ["echo",
                                                                                              "window_options"]
    _, echo = small_scene()
    with pytest.raises(TypeError, match="positional"):
        ptrs_image(echo, None, 8.0)
    sinc = ptrs_image(echo, block_width=8.0, backend="opencl")
    linear = ptrs_image(echo, block_width=8.0, interp="linear", backend="opencl")
    knab = ptrs_image(echo, block_width=8.0, tap_window="knab", backend="opencl")
    assert (sinc.provenance["interp"], linear.provenance["interp"], knab.provenance["tap_window"]) == \
        ("sinc8", "linear", "knab")
    peak = np.abs(sinc.data).max()
    # the options reach the correction: the images differ, by what the interpolators differ in
    # (largest difference over the peak, measured: linear 0.10, its attenuation of the range
    # band's edge; Knab's window 0.013, sinc16 0.009)
    for other, low, high in ((linear, 0.02, 0.3), (knab, 1e-3, 0.05)):
        diff = np.abs(other.data - sinc.data).max() / peak
        assert low < diff < high, diff


def test_rcmc_resampling_checked_once_is_resample(opencl_device):
    """ptrs_image's correction calls clsas.interp.resample_prechecked (its checks done once an
    image): on the positions it builds, that is resample's result on both backends."""
    from clsas.interp import resample, resample_prechecked

    rng = np.random.default_rng(3)
    src = (rng.standard_normal((37, 300)) + 1j * rng.standard_normal((37, 300))).astype(np.complex64)
    positions = 40.0 + np.arange(200)[None, :] * 1.003 + rng.uniform(-3, 3, (37, 1))
    for backend in ("numpy", "opencl"):
        for interp in ("linear", "sinc8"):
            a = resample(src, positions, interp, backend=backend)
            b = resample_prechecked(src, positions, interp, backend=backend)
            assert a.dtype == b.dtype and np.array_equal(a, b), (backend, interp)


def test_records_on_the_common_range_axis():
    """A record that starts a whole number of samples after the common axis is copied there (no
    filter); otherwise delayed by a linear phase in range frequency. The copy is what the filter
    gives for a whole-sample delay (to float32 rounding), and the filter's delay is the record's
    (a half-sample delay read back by sinc interpolation)."""
    from clsas.image.ptrs.imaging import _slow_time_spectrum

    rng = np.random.default_rng(5)
    fs, n_r, n_fp = 25e3, 96, 16
    data = (rng.standard_normal((12, 40)) + 1j * rng.standard_normal((12, 40))).astype(np.complex64)
    ftau = np.fft.fftfreq(n_r, 1 / fs)
    copied = _slow_time_spectrum(data, 7 / fs, fs, ftau, n_r, n_fp, workers=1)
    assert copied.dtype == np.complex64 and copied.shape == (n_fp, n_r)
    assert np.array_equal(copied[:, 7:47], scipy.fft.fft(data, n=n_fp, axis=0))
    assert not copied[:, :7].any() and not copied[:, 47:].any()
    spec = np.fft.fft(data, n=n_r, axis=1) * np.exp(-2j * np.pi * ftau * 7 / fs)
    filtered = np.fft.fft(np.fft.ifft(spec, axis=1), n=n_fp, axis=0)
    assert np.abs(copied - filtered).max() < 1e-5 * np.abs(filtered).max()
    half = _slow_time_spectrum(data, 7.5 / fs, fs, ftau, n_r, n_fp, workers=1)
    spec = np.fft.fft(data, n=n_r, axis=1) * np.exp(-2j * np.pi * ftau * 7.5 / fs)
    assert np.abs(half - np.fft.fft(np.fft.ifft(spec, axis=1), n=n_fp, axis=0)).max() < 1e-5 * np.abs(half).max()
