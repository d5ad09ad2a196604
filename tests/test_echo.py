"""Echo synthesis: OpenCL kernels vs NumPy reference, delay physics, amplitude, noise, bad input.

The kernels: kernels/echo_paths.cl (echo_paths: delays and amplitudes; echo_extents, echo_spread)
against clsas/synthesis/paths.py and clsas/geometry.py (the delays tests), and
kernels/echo_accumulate.cl (echo_bounds, echo_accumulate) against clsas/synthesis/echo/reference.py
(reference_and_kernel: every sample of the same options)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from _tolerances import phase_error, rel_l2

from clsas import metrics
from clsas.errors import MemoryBudgetError
from clsas.image import range_compress
from clsas.scene import presets
from clsas.scene.scenario import (
    Array,
    Medium,
    Platform,
    PulseSchedule,
    Recording,
    Scenario,
    Waveform,
)
from clsas.scene.targets import PointTargets
from clsas.synthesis import SynthesisOptions, delays, simulate, synthesize


def kiang(n_pulses=8, fs_factor=1.0, **changes):
    """Kiang & Kiang 2022 Table I sonar (A, towed B, sonobuoy C), optionally oversampled."""
    sc = presets.kiang2022(n_pulses=n_pulses)
    wf = dataclasses.replace(sc.waveform, fs=fs_factor * sc.waveform.bandwidth)
    return sc.replace(waveform=wf, **changes)


def reference_and_kernel(sc, precision="single", **kw):
    """The float64 NumPy reference (complex128) and the OpenCL kernel's samples (complex64, or
    complex128 with precision="double") of the same options."""
    common = dict(progress=False, max_bytes=2**31, chunk_bytes=2**26, stop_and_go=kw.get("stop_and_go", False),
                  spreading=kw.get("spreading", False))
    ref = synthesize(sc, SynthesisOptions(backend="numpy", dtype=np.complex128, **common), kw.get("occlusion"))
    got = synthesize(sc, SynthesisOptions(backend="opencl", precision=precision,
                                          dtype=np.complex128 if precision == "double" else np.complex64, **common),
                     kw.get("occlusion"))
    np.testing.assert_array_equal(ref.t0, got.t0)
    return ref.data, got.data


# ---------------------------------------------------------------- delays

@pytest.mark.filterwarnings("ignore::clsas.scene.scenario.SamplingWarning")  # Zhang's table as printed
@pytest.mark.parametrize("r", [30.0, 141.0, 2000.0])
def test_delays_match_zhang_eq1(backend, r):
    """Zhang et al. 2019 eq. (1): straight track, stationary target at (r, 0), receiver at +d_i."""
    sc = presets.zhang2019(n_pulses=9).replace(targets=(PointTargets([r, 0.0, 0.0]),))
    tau = delays(sc, backend=backend)[:, :, 0]  # (receivers, pulses)
    c, v = sc.medium.sound_speed, sc.platform.speed
    t = sc.eta[None, :]
    d = sc.array.rx_offsets[:, 1][:, None]
    b = v * (v * t + d) + c * np.sqrt(v**2 * t**2 + r**2)
    expected = (b + np.sqrt(b**2 + (c**2 - v**2) * (2 * v * t * d + d**2))) / (c**2 - v**2)
    assert np.max(np.abs(tau - expected)) < 1e-9


def test_stop_and_go_delays_are_geometric(backend):
    sc = kiang(4).replace(targets=(PointTargets([[1989.0, 5.0, -350.0]], velocity=(0, -4, 0)),))
    tau = delays(sc, backend=backend, stop_and_go=True)
    q = np.array([1989.0, 5.0, -350.0]) + np.outer(sc.eta, [0, -4, 0])
    for h in range(3):
        expected = (np.linalg.norm(q - sc.tx_position(sc.eta), axis=1)
                    + np.linalg.norm(q - sc.receiver_position(h, sc.eta), axis=1)) / sc.medium.sound_speed
        assert np.max(np.abs(tau[h, :, 0] - expected)) < 1e-9


def test_kernel_delays_match_reference_with_moving_targets(opencl_device, rng):
    """kernels/echo_paths.cl echo_paths's delays against the float64 NumPy delays."""
    n = 40
    pos = np.column_stack([rng.uniform(30, 2000, n), rng.uniform(-50, 50, n), rng.uniform(-300, 0, n)])
    sc = kiang(6).replace(targets=(PointTargets(pos, velocity=rng.uniform(-5, 5, (n, 3)) / np.sqrt(3)),))
    assert np.max(np.abs(delays(sc, "opencl") - delays(sc, "numpy"))) < 1e-9


# ---------------------------------------------------------------- kernel vs reference

def isolated_scene(rng, f0=150e3):
    """Scatterers 30 m .. 2 km away, 100 m apart in range (echoes never overlap), moving."""
    x = np.arange(30.0, 2000.0, 100.0)
    pos = np.column_stack([x, rng.uniform(-20, 20, x.size), rng.uniform(-100, 0, x.size)])
    targets = PointTargets(pos, reflectivity=np.exp(2j * np.pi * rng.random(x.size)),
                           velocity=rng.uniform(-3, 3, (x.size, 3)))
    sc = kiang(6, fs_factor=1.25, targets=(targets,))
    wf = dataclasses.replace(sc.waveform, f0=f0)
    return sc.replace(waveform=wf)


@pytest.mark.parametrize("f0", [50e3, 150e3])
def test_kernel_phase_error_per_contribution(opencl_device, rng, f0):
    # every nonzero sample holds exactly one contribution: its phase error is the contribution's
    ref, got = reference_and_kernel(isolated_scene(rng, f0))
    on = np.abs(ref) > 0.5
    assert on.sum() > 3 * 6 * 19 * 90
    # float32 accumulation against float64; ~10x the measured errors (phase 2.8e-5 rad, relative
    # L2 4.5e-6 at both carriers) so that a regression shows long before the 0.01 rad budget
    assert phase_error(got[on], ref[on]).max() < 3e-4
    assert np.max(np.abs(np.abs(got[on]) - np.abs(ref[on]))) < 1e-4
    assert rel_l2(got, ref) < 5e-5


def test_kernel_dense_scene_relative_l2(opencl_device, rng):
    n = 300
    pos = np.array([1000.0, 0.0, -200.0]) + rng.uniform(-10, 10, (n, 3))
    targets = PointTargets(pos, reflectivity=rng.standard_normal(n) + 1j * rng.standard_normal(n),
                           velocity=(1.0, -2.0, 0.5))
    near = PointTargets(np.array([30.0, 0.0, -43.0]) + rng.uniform(-2, 2, (20, 3)))
    ref, got = reference_and_kernel(kiang(5, targets=(targets, near)))
    assert rel_l2(got, ref) < 6e-5  # measured 5.6e-6


def test_kernel_double_precision_agrees_to_1e9(opencl_device, rng):
    ref, got = reference_and_kernel(isolated_scene(rng), precision="double")
    assert got.dtype == np.complex128
    assert rel_l2(got, ref) < 1e-9


def test_kernel_with_motion_errors_and_element_patterns(opencl_device, rng):
    platform = Platform(speed=1.5, start=(0, 0, -20), sway=lambda t: 0.05 * np.sin(0.7 * t),
                        heave=lambda t: 0.02 * np.cos(0.3 * t), yaw=lambda t: 0.02 * np.sin(0.5 * t),
                        pitch=lambda t: 0.01 * np.cos(0.4 * t))
    array = Array.uniform_line(4, 0.05, first=-0.1, tx_length=0.1, rx_length=0.05)
    sc = Scenario(Medium(1500.0), Waveform(f0=100e3, bandwidth=20e3, duration=4e-3, fs=25e3), platform, array,
                  PulseSchedule(prf=20.0, n_pulses=6),
                  targets=(PointTargets(np.column_stack([rng.uniform(40, 120, 10), rng.uniform(-3, 3, 10),
                                                         np.full(10, -20.0)])),))
    ref, got = reference_and_kernel(sc, spreading=True)
    # measured: relative L2 1.9e-4, 99th percentile phase 4.8e-4 rad (linear receiver motion
    # between nodes, lambda / 10^4 by construction); bounds ~10x
    assert rel_l2(got, ref) < 2e-3
    on = np.abs(ref) > 1e-3 * np.abs(ref).max()
    assert np.percentile(phase_error(got[on], ref[on]), 99) < 5e-3


def _aligned_equal(a, b, tol=1e-5) -> bool:
    """The two echoes agree on their common fast-time span, receiver by receiver."""
    for h in range(a.n_rx):
        shift = int(round((b.t0[h] - a.t0[h]) * a.fs))
        n = min(a.n_samples - shift, b.n_samples)
        if rel_l2(a.data[h, :, shift:shift + n], b.data[h, :, :n]) > tol:
            return False
    return True


def test_occlusion_factor_removes_paths(backend):
    pos = np.array([[1989.0, 0.0, -350.0], [1995.0, 3.0, -350.0]])
    sc = kiang(4, targets=(PointTargets(pos),))
    hidden = np.ones((3, 4, 2))
    hidden[:, :, 1] = 0
    with_occlusion = simulate(sc, backend=backend, occlusion=hidden, progress=False)
    first_only = simulate(sc.replace(targets=(PointTargets(pos[:1]),)), backend=backend, progress=False)
    assert _aligned_equal(with_occlusion, first_only)
    as_callable = simulate(sc, backend=backend, occlusion=lambda pulses: hidden[:, pulses], progress=False,
                           chunk_bytes=1)
    np.testing.assert_array_equal(as_callable.data, with_occlusion.data)
    dark = simulate(sc, backend=backend, occlusion=np.zeros((3, 4, 2)), progress=False)
    assert not np.any(dark.data)


def test_chunking_does_not_change_the_result(backend, rng):
    pos = np.array([1989.0, 0.0, -350.0]) + rng.uniform(-5, 5, (30, 3))
    sc = kiang(7, targets=(PointTargets(pos, velocity=(0, -4, 0)),))
    whole = simulate(sc, backend=backend, progress=False)
    pieces = simulate(sc, backend=backend, progress=False, chunk_bytes=1)
    np.testing.assert_allclose(pieces.data, whole.data, rtol=0, atol=1e-6)


# ---------------------------------------------------------------- physics

def compressed_peaks(data, backend):
    """Refined fast time of the strongest peak of every (receiver, pulse) record."""
    rc = range_compress(simulate(data, backend=backend, progress=False, intra_pulse="none"), upsample=4)
    peaks = np.empty(rc.data.shape[:2])
    phases = np.empty(rc.data.shape[:2])
    for h in range(rc.n_rx):
        for p in range(rc.n_pulses):
            pr = metrics.point_response(rc.data[h, p], rc.fast_time(h))
            peaks[h, p], phases[h, p] = pr.location, np.angle(pr.peak)
    return peaks, phases, rc


@pytest.mark.parametrize("velocity", [(0.0, 0.0, 0.0), (1.0, -4.0, 0.5)])
def test_compressed_peaks_follow_the_exact_delays(backend, velocity):
    sc = kiang(12, fs_factor=2.0, targets=(PointTargets([1989.0, 0.0, -350.0], velocity=velocity),))
    peaks, _, rc = compressed_peaks(sc, backend)
    tau = delays(sc, backend="numpy")[:, :, 0]
    assert np.max(np.abs(peaks - tau)) * rc.fs / 4 < 1 / 20  # 1/20 of an input sample
    if any(velocity):  # the moving target's delays really move (several samples over the pulses)
        assert np.ptp(tau[0]) * sc.waveform.fs > 1


def test_non_stop_and_go_differs_by_the_predicted_delay(backend):
    sc = kiang(6, fs_factor=2.0, targets=(PointTargets([1989.0, 40.0, -350.0], velocity=(0, -4, 0)),))
    exact, exact_phase, rc = compressed_peaks(sc, backend)
    sag = simulate(sc, backend=backend, stop_and_go=True, progress=False, intra_pulse="none")
    rc_sag = range_compress(sag, upsample=4)
    predicted = delays(sc, "numpy")[:, :, 0] - delays(sc, "numpy", stop_and_go=True)[:, :, 0]
    assert np.max(np.abs(predicted)) * sc.waveform.fs > 0.05  # a measurable shift (B: ~0.5 ms)
    for h in range(3):
        for p in range(6):
            a = metrics.point_response(rc.data[h, p], rc.fast_time(h))
            b = metrics.point_response(rc_sag.data[h, p], rc_sag.fast_time(h))
            assert abs((a.location - b.location) - predicted[h, p]) * sc.waveform.fs < 1 / 20
            dphi = np.angle(a.peak * np.conj(b.peak) * np.exp(2j * np.pi * sc.waveform.f0 * predicted[h, p]))
            assert abs(dphi) < 0.05


def test_element_pattern_attenuates_off_broadside(backend):
    wf = Waveform(f0=150e3, bandwidth=20e3, duration=5e-3, fs=40e3)
    length = 0.1  # L sin(theta) / lambda = 0.5 at sin(theta) = 0.05
    array = Array(rx_offsets=[[0.0, 0.0, 0.0]], tx_length=length, rx_length=length)
    r_off = 130.0  # 30 m behind the broadside target: the two echoes do not overlap
    targets = PointTargets([[100.0, 0.0, 0.0], [r_off * np.sqrt(1 - 0.05**2), r_off * 0.05, 0.0]])
    sc = Scenario(Medium(1500.0), wf, Platform(speed=0.01), array, PulseSchedule(prf=1.0, n_pulses=1),
                  targets=(targets,))
    rc = range_compress(simulate(sc, backend=backend, progress=False))
    broadside = metrics.point_response(rc.data[0, 0], rc.fast_time(0))
    tau_off = delays(sc, "numpy")[0, 0, 1]
    cut = rc.data[0, 0]
    k = int(round((tau_off - rc.t0[0]) * rc.fs))
    off = metrics.point_response(cut[k - 60:k + 60], rc.fast_time(0)[k - 60:k + 60])
    expected = np.sinc(0.5) ** 2  # transmit x receive
    assert abs(abs(off.peak) / abs(broadside.peak) - expected) < 0.01 * expected


def test_measured_snr_matches(backend):
    sc = kiang(16, targets=(PointTargets([[1989.0, 0.0, -350.0], [1995.0, 10.0, -350.0]]),))
    clean = simulate(sc, backend=backend, progress=False)
    noisy = simulate(sc, backend=backend, snr_db=-5.0, seed=7, progress=False)
    again = simulate(sc, backend=backend, snr_db=-5.0, seed=7, progress=False)
    np.testing.assert_array_equal(noisy.data, again.data)
    noise = noisy.data - clean.data
    n_valid = noisy.provenance["n_valid"]
    for h in range(3):
        on = np.abs(clean.data[h]) > 0
        recorded = noise[h, :, :n_valid[h]]
        snr = 10 * np.log10(np.mean(np.abs(clean.data[h][on]) ** 2) / np.mean(np.abs(recorded) ** 2))
        assert abs(snr - (-5.0)) < 0.2
        assert not np.any(noise[h, :, n_valid[h]:])  # nothing is recorded beyond the window


def test_recording_window_drops_samples_never_wraps(backend):
    sc = kiang(4, targets=(PointTargets([1989.0, 0.0, -350.0]),))
    full = simulate(sc, backend=backend, progress=False)
    n = full.n_samples
    t0 = full.t0 + 40 / full.fs
    cut = simulate(sc.replace(recording=Recording(t0=t0, n_samples=n - 80)), backend=backend, progress=False)
    # the same samples, up to the float kernel's rounding: its chirp phases (up to BT/8 = 12.5
    # cycles) carry ~1e-6 cycle of float32 error and the rows start at other samples in the two
    # runs, so the two roundings differ by up to a few 1e-5 of the unit amplitude
    np.testing.assert_allclose(cut.data, full.data[:, :, 40:n - 40], atol=5e-5)


def test_echo_data_geometry(backend):
    sc = kiang(5, targets=(PointTargets([1989.0, 0.0, -350.0]),))
    out = simulate(sc, backend=backend, progress=False)
    assert out.receivers == ("A", "B", "C") and not out.compressed
    np.testing.assert_allclose(out.tx_pos, sc.tx_position(sc.eta))
    tau = delays(sc, "numpy")[:, :, 0]
    for h in range(3):
        np.testing.assert_allclose(out.rx_position(h, tau[h]), sc.receiver_position(h, sc.eta + tau[h]), atol=1e-9)


@pytest.mark.parametrize("name", sorted(presets.POINT_LAYOUTS))
def test_point_scene_presets_simulate(opencl_device, name):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # zhang2019 warns (documented undersampling)
        sc = presets.point_scene(name, n_pulses=4)
    counts = {"huang2022": (6, 32), "zhang2019": (18, 30), "wu2018": (5, 32), "heremans2009": (9, 15)}
    assert (sc.targets[0].positions.shape[0], sc.n_receivers) == counts[name]
    out = simulate(sc, backend="opencl", progress=False)
    assert np.all(np.abs(out.data).max(axis=2) > 0)  # every receiver hears every pulse


# ---------------------------------------------------------------- bad input

def test_bad_input_is_refused():
    target = PointTargets([1989.0, 0.0, -350.0])
    with pytest.raises(ValueError, match="n_pulses"):
        PulseSchedule(prf=80.0, n_pulses=0)
    with pytest.raises(ValueError, match="no receivers"):
        Scenario(Medium(), presets.kiang2022(1).waveform, Platform(speed=1.0), Array(np.zeros((0, 3))),
                 PulseSchedule(prf=1.0, n_pulses=1))
    with pytest.raises(ValueError, match="positions"):
        PointTargets([np.nan, 0.0, 0.0])
    with pytest.raises(ValueError, match="velocity"):
        PointTargets([1.0, 0.0, 0.0], velocity=(0.0, 2000.0, 0.0))
    sc = kiang(4)
    with pytest.raises(ValueError, match="targets is empty"):
        simulate(sc, backend="numpy", progress=False)
    sc = sc.replace(targets=(target,))
    with pytest.raises(MemoryBudgetError, match="max_bytes allows"):  # the CLI catches it by kind
        simulate(sc, backend="numpy", progress=False, max_bytes=1000)
    with pytest.raises(ValueError, match="shorter recording window"):
        simulate(sc.replace(recording=Recording(t0=0.0, n_samples=10**9)), backend="numpy", progress=False)
    with pytest.raises(ValueError, match="outside every recording window"):
        simulate(sc.replace(recording=Recording(t0=0.0, n_samples=1000)), backend="numpy", progress=False)
    with pytest.raises(ValueError, match="occlusion"):
        simulate(sc, backend="numpy", progress=False, occlusion=np.ones((3, 4, 2)))
    with pytest.raises(ValueError, match="snr_db"):
        simulate(sc, backend="numpy", progress=False, snr_db=np.nan)
    with pytest.raises(TypeError, match="scenario"):
        simulate("kiang", backend="numpy")

    with pytest.raises(TypeError, match="targets"):
        sc.replace(targets=(np.zeros(3),))


def test_scatterer_on_a_receiver_is_refused(backend):
    at_buoy = kiang(4).replace(targets=(PointTargets([[-500.0, 0.0, -150.0]]),))  # on sonobuoy C
    with pytest.raises(ValueError, match="coincides"), np.errstate(all="ignore"):
        simulate(at_buoy, backend=backend, progress=False, spreading=True)


@pytest.mark.slow
def test_scales_to_1e5_scatterers_with_bounded_memory(opencl_device):
    import resource

    rng = np.random.default_rng(3)
    pos = np.array([1989.0, 0.0, -350.0]) + rng.uniform(-0.5, 0.5, (100_000, 3)) * [8.0, 62.0, 8.0]
    sc = kiang(1024, targets=(PointTargets(pos, velocity=(0, -4, 0)),))
    out = simulate(sc, backend="opencl", progress=False, chunk_bytes=64 * 2**20)
    assert out.data.shape[:2] == (3, 1024) and np.all(np.abs(out.data).max(axis=2) > 0)
    # 3 x 1024 x ~600 samples of complex64 is 15 MB; the path records of all pulses would be 4.9 GB
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 < 4 * 2**30


# ---------------------------------------------------------------- options and the public reference

@pytest.mark.parametrize("option,value,error", [
    ("precision", "half", ValueError), ("dtype", np.float32, ValueError), ("dtype", "bogus", ValueError),
    ("stop_and_go", "yes", TypeError), ("spreading", 1, TypeError), ("progress", None, TypeError),
    ("max_bytes", 0, ValueError), ("chunk_bytes", -5, ValueError), ("max_bytes", True, TypeError),
    ("reuse_tolerance", -1.0, ValueError), ("reuse_tolerance", np.nan, ValueError), ("backend", "cuda", ValueError),
])
def test_options_are_checked_once_naming_the_option(option, value, error):
    with pytest.raises(error, match=option if option != "backend" else "backend"):
        SynthesisOptions(**{option: value})


def test_options_are_frozen_and_normalised():
    opts = SynthesisOptions(backend="numpy", dtype="complex128", max_bytes=np.int64(2**30), reuse_tolerance=0)
    assert opts.backend == "numpy" and opts.dtype == np.complex128 and not opts.double
    assert type(opts.max_bytes) is int and type(opts.reuse_tolerance) is float
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.stop_and_go = True


def test_synthesize_gives_the_float64_reference_simulate_rounds():
    """synthesize(backend="numpy", dtype=complex128) is the reference simulate() returns in
    complex64: the same samples up to float32 rounding, the same windows."""
    sc = kiang(4, targets=(PointTargets([[1989.0, 5.0, -350.0], [40.0, -2.0, -45.0]]),))
    ref = synthesize(sc, SynthesisOptions(backend="numpy", dtype=np.complex128, progress=False))
    echo = simulate(sc, backend="numpy", progress=False)
    assert ref.data.dtype == np.complex128 and echo.data.dtype == np.complex64
    np.testing.assert_array_equal(ref.t0, echo.t0)
    np.testing.assert_array_equal(ref.data.astype(np.complex64), echo.data)
    with pytest.raises(TypeError, match="options"):
        synthesize(sc, {"backend": "numpy"})
