"""Propagation: Francois-Garrison absorption and its envelope over the pulse, intra-pulse Doppler
against the exact per-sample solution, multipath delays against closed-form image sources."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from _tolerances import phase_error, rel_l2

from clsas import metrics
from clsas.geometry import incoming, meet_time, outgoing
from clsas.image import range_compress
from clsas.model import Medium, Waveform
from clsas.scene import presets
from clsas.scene.scenario import Array, Platform, PulseSchedule, Scenario
from clsas.scene.seafloor import Seafloor
from clsas.scene.surface import SeaSurface
from clsas.scene.targets import PointTargets
from clsas.synthesis import SynthesisOptions, delays, simulate, synthesize
from clsas.synthesis.propagation import BandAbsorption, absorption_db_per_km, boundaries, path_kinds

# ---------------------------------------------------------------- absorption


def test_absorption_matches_arlpy_documented_values():
    """arlpy (ARL, NUS) documents its Francois-Garrison uwa.absorption(50 kHz) at T = 27 deg C,
    S = 35 ppt, depth 10 m, pH 8.1: -10.71 dB over 1 km and -32.13 dB over 3 km (its doctest).
    arlpy itself is not a test dependency: it pins numpy < 2. Checked by hand against arlpy
    1.9.3's formula over T -2..30 deg C, S 30..40, depth 0..3000 m, pH 7.5..8.3, 100 Hz..1 MHz:
    relative difference 2e-12."""
    medium = Medium(temperature=27.0, salinity=35.0, depth=10.0, ph=8.1)
    a = absorption_db_per_km(50e3, medium)
    assert a == pytest.approx(10.71, abs=0.005)
    assert 3 * a == pytest.approx(32.13, abs=0.005)


def test_absorption_terms_follow_their_relaxations():
    """Francois & Garrison's structure: below the boric acid relaxation (~1 kHz) the absorption
    grows as f^2 and depends on pH, between the relaxations MgSO4 dominates (pH barely
    matters), far above both the pure-water f^2 term; more depth, less absorption."""
    base = Medium(temperature=10.0)
    low = absorption_db_per_km(np.array([100.0, 200.0]), base)
    assert low[1] / low[0] == pytest.approx(4.0, rel=0.05)
    acid = absorption_db_per_km(300.0, dataclasses.replace(base, ph=7.7)) / absorption_db_per_km(300.0, base)
    assert acid < 0.7  # boric acid's term scales with 10^(0.78 pH)
    mid = absorption_db_per_km(100e3, dataclasses.replace(base, ph=7.7)) / absorption_db_per_km(100e3, base)
    assert mid == pytest.approx(1.0, abs=0.01)
    high = absorption_db_per_km(np.array([5e6, 1e7]), base)
    assert high[1] / high[0] == pytest.approx(4.0, rel=0.02)
    assert absorption_db_per_km(100e3, dataclasses.replace(base, depth=3000.0)) < absorption_db_per_km(100e3, base)


def test_band_fit_is_within_its_stated_error():
    for wf in (Waveform(f0=150e3, bandwidth=20e3, duration=10e-3, fs=25e3),
               Waveform(f0=100e3, bandwidth=100e3, duration=5e-3, fs=125e3)):
        fit = BandAbsorption.of(Medium(), wf)
        df = np.linspace(-0.5, 0.5, 1001) * wf.bandwidth
        exact = absorption_db_per_km(wf.f0 + df, Medium()) * np.log(10) / 20 / 1e3
        assert np.max(np.abs(fit.a0 + fit.a1 * df + fit.a2 * df * df - exact)) <= 1.01 * fit.error
        assert fit.error < 1e-2 * fit.a0


def single_path_scene(distance=300.0, **medium):
    """One omnidirectional transceiver (nearly at rest: 1 cm/s), one point ``distance`` m away."""
    sc = Scenario(Medium(**medium), Waveform(f0=150e3, bandwidth=60e3, duration=4e-3, fs=75e3), Platform(speed=0.01),
                  Array(rx_offsets=[[0.0, 0.0, 0.0]]), PulseSchedule(prf=1.0, n_pulses=1))
    return sc.replace(targets=(PointTargets([distance, 0.0, 0.0]),))


@pytest.mark.parametrize("backend_name", ["numpy", "opencl"])
def test_absorption_envelope_along_the_pulse(backend_name, request):
    """|s| along the echo is exp(-R a(f0 + K u)) at the pulse's instantaneous frequency (module
    docstring of clsas.synthesis.propagation): within 2e-4 relative of Francois-Garrison at every
    sample of a 40 % band over 600 m (2 x 300 m), where the loss varies by ~4 dB across the band,
    within the quadratic fit's stated error (BandAbsorption.error x R: 1.8e-3 here)."""
    if backend_name == "opencl":
        request.getfixturevalue("opencl_device")
    sc = single_path_scene(temperature=4.0)
    out = synthesize(sc, SynthesisOptions(backend=backend_name, absorption=True, progress=False,
                                          dtype=np.complex128 if backend_name == "numpy" else np.complex64))
    wf, c = sc.waveform, sc.medium.sound_speed
    tau0 = 2 * 300.0 / c
    t = out.t0[0] + np.arange(out.data.shape[2]) / wf.fs
    u = t - tau0
    inside = np.abs(u) < 0.5 * wf.duration - 1 / wf.fs
    expected = 10 ** (-absorption_db_per_km(wf.f0 + wf.chirp_rate * u[inside], sc.medium) * 0.6 / 20)
    got = np.abs(out.data[0, 0, inside])
    assert np.ptp(20 * np.log10(expected)) > 3  # the band really tilts the echo
    bound = 600.0 * BandAbsorption.of(sc.medium, wf).error
    assert bound < 5e-3
    assert np.max(np.abs(got / expected - 1)) < bound + 1e-5


# ---------------------------------------------------------------- intra-pulse Doppler


def exact_record(sc: Scenario, h: int, p: int, target: PointTargets, t0: float, n: int) -> np.ndarray:
    """The echo of one point at receiver h, pulse p, sample by sample with nothing linearised:
    the sample at fast time tau receives the wavelet emitted at eta + u from T(eta + u) with
    u + D(u) = tau, D(u) its exact two-way delay (fixed points of clsas.geometry on the
    scenario's trajectories), solved by iterating u <- tau - D(u)."""
    wf, c = sc.waveform, sc.medium.sound_speed
    eta = sc.eta[p]
    tau = t0 + np.arange(n) / wf.fs
    u = tau - 2 * np.linalg.norm(target.positions[0] - sc.tx_position(eta)) / c
    for _ in range(12):
        emit = eta + u
        t1, q = outgoing(sc.tx_position(emit), emit, target.positions, target.velocity, c, 1e-15, False)
        t2, _ = incoming(lambda t: sc.receiver_position(h, t), emit, t1, q, c, 1e-15, False)
        u = tau - (t1 + t2)[:, 0]
    inside = np.abs(u) <= 0.5 * wf.duration
    return np.where(inside, np.exp(1j * np.pi * wf.chirp_rate * u * u - 2j * np.pi * wf.f0 * (tau - u)), 0.0)


def doppler_scene():
    """Kiang & Kiang's sonar (A moving, B towed 250 m behind, sonobuoy C) and a point 300 m off
    closing at ~5 m/s: about 2.5 carrier cycles of Doppler over half the pulse."""
    sc = presets.kiang2022(n_pulses=3)
    sc = sc.replace(waveform=dataclasses.replace(sc.waveform, fs=25e3))
    return sc.replace(targets=(PointTargets([300.0, 20.0, -60.0], velocity=(-5.0, 2.0, 0.5)),))


@pytest.mark.parametrize("backend_name", ["numpy", "opencl"])
def test_intra_pulse_doppler_matches_the_exact_per_sample_solution(backend_name, request):
    if backend_name == "opencl":
        request.getfixturevalue("opencl_device")
    sc = doppler_scene()
    out = synthesize(sc, SynthesisOptions(backend=backend_name, progress=False, dtype=np.complex128,
                                          precision="single", intra_pulse="moving"))
    plain = synthesize(sc, SynthesisOptions(backend="numpy", progress=False, dtype=np.complex128, intra_pulse="none"))
    wf = sc.waveform
    for h in range(sc.n_receivers):
        for p in range(sc.eta.size):
            exact = exact_record(sc, h, p, sc.targets[0], out.t0[h], out.data.shape[2])
            on = np.abs(exact) > 0
            core = on & np.roll(on, 2) & np.roll(on, -2)  # the pulse's edges fall within a sample
            got = out.data[h, p]
            # ~10x the measured error (numpy 2.2e-6 rad, the quadratic D(u); opencl 1.8e-5 rad, its
            # float32 chirp; relative L2 8e-7 and 6e-6)
            assert phase_error(got[core], exact[core]).max() < 2e-4, (h, p)
            assert rel_l2(got[core], exact[core]) < 6e-5
            # what the single-delay echo misses: radians, not a rounding
            assert phase_error(plain.data[h, p][core], exact[core]).max() > 1.0
    assert wf.duration * wf.fs > 100


def test_compressed_peak_moves_by_the_range_doppler_coupling(backend):
    """An LFM Doppler-shifted by f_D peaks after matched filtering at tau - f_D / K (range-Doppler
    coupling); f_D = -f0 D'(0), D' from the exact delays of wavelets emitted 0.1 ms apart."""
    sc = doppler_scene()
    rc = range_compress(simulate(sc, backend=backend, progress=False, intra_pulse="moving"), upsample=8)
    wf, c = sc.waveform, sc.medium.sound_speed
    target = sc.targets[0]
    for h in range(sc.n_receivers):
        for p in range(sc.eta.size):
            d = []
            for u in (-1e-4, 0.0, 1e-4):
                emit = np.array([sc.eta[p] + u])
                t1, q = outgoing(sc.tx_position(emit), emit, target.positions, target.velocity, c, 1e-15, False)
                t2, _ = incoming(lambda t: sc.receiver_position(h, t), emit, t1, q, c, 1e-15, False)
                d.append(float((t1 + t2)[0, 0]))
            slope = (d[2] - d[0]) / 2e-4
            f_doppler = -wf.f0 * slope / (1 + slope)
            expected = d[1] - f_doppler / (wf.chirp_rate / (1 + slope) ** 2)
            peak = metrics.point_response(rc.data[h, p], rc.fast_time(h)).location
            assert abs(f_doppler / wf.chirp_rate) * wf.fs > 2  # the shift is samples, not a rounding
            assert abs(peak - expected) * wf.fs < 1 / 20, (h, p)


# ---------------------------------------------------------------- multipath


def shallow_scene(order_target=(45.0, 3.0, -32.0), speed=2.0):
    """A ``speed`` m/s platform 20 m below a flat surface over a sand bottom 50 m down (its mean
    plane reflects; its speckle is a 30 cm patch 150 m off), a 2-element array (transmitter at
    the first), one stationary point in the water column."""
    floor = Seafloor((150.0, 150.3, -0.15, 0.15), -50.0, sediment="sand")  # its facets echo long after the point
    sc = Scenario(Medium(1500.0), Waveform(f0=100e3, bandwidth=20e3, duration=2e-3, fs=25e3),
                  Platform(speed=speed, start=(0.0, 0.0, -20.0)), Array(rx_offsets=[[0.0, 0.0, 0.0], [0.0, 0.5, 0.0]]),
                  PulseSchedule(prf=5.0, n_pulses=4), seafloor=floor, surface=SeaSurface(0.0))
    return sc.replace(targets=(PointTargets(list(order_target)),))


def image_delays(sc: Scenario, out_planes: str, back_planes: str) -> np.ndarray:
    """Closed-form image-source delays (H, P) of the one stationary point: the transmitter mirrored
    in the outgoing leg's planes, the receiver (moving uniformly) in the return leg's, each leg
    the meeting time of a straight line (clsas.geometry.meet_time)."""
    z = {"S": 0.0, "B": -50.0}

    def mirror(point, planes):
        out = np.array(point, dtype=float)
        for name in planes.replace("D", ""):
            out[..., 2] = 2 * z[name] - out[..., 2]
        return out

    c = sc.medium.sound_speed
    q = sc.targets[0].positions[0]
    v = np.array([0.0, sc.platform.speed, 0.0])
    out = np.empty((sc.n_receivers, sc.eta.size))
    for p, eta in enumerate(sc.eta):
        t1 = np.linalg.norm(q - mirror(sc.tx_position(eta), out_planes)) / c
        for h in range(sc.n_receivers):
            r = mirror(sc.receiver_position(h, eta + t1), back_planes)
            out[h, p] = t1 + meet_time((r - q)[None], v[None], c)[0]
    return out


@pytest.mark.parametrize("path", ["D-D", "S-D", "D-B", "B-S", "SB-D", "D-BS", "S-S"])
def test_multipath_delays_match_closed_form_image_sources(backend, path):
    sc = shallow_scene()
    out_planes, back_planes = path.split("-")
    expected = image_delays(sc, out_planes, back_planes)
    got = delays(sc, backend=backend, path=path)[:, :, 0]
    assert np.max(np.abs(got - expected)) * sc.waveform.fs < 1 / 20
    assert np.max(np.abs(got - expected)) < 1e-9  # both exact: they agree far below the budget


def test_multipath_echo_peaks_at_the_image_delays_with_their_coefficients(backend):
    """The first-order echo of a point: the direct peak, the two surface paths (S-D, D-S, equal
    delays for a transceiver at rest: the platform creeps at 1 cm/s) at -2 x the direct amplitude,
    and the two bottom paths at 2 V(theta) (the sand's Rayleigh coefficient at their grazing
    angle), each at its image delay."""
    sc = shallow_scene(speed=0.01)
    echo = simulate(sc, backend=backend, progress=False, intra_pulse="none", spreading=False, absorption=False)
    assert echo.provenance["paths"] == ["D-D", "D-S", "D-B", "S-D", "B-D"]
    rc = range_compress(echo, upsample=8)
    t = rc.fast_time(0)
    direct = image_delays(sc, "D", "D")[0, 0]
    surface = image_delays(sc, "S", "D")[0, 0]
    bottom = image_delays(sc, "B", "D")[0, 0]
    q = sc.targets[0].positions[0]
    tx = sc.tx_position(sc.eta[0])
    image = tx.copy()
    image[2] = -100.0 - image[2]
    grazing = np.arcsin(abs(q[2] - image[2]) / np.linalg.norm(q - image))
    v_bottom = complex(sc.seafloor.sediment.reflection_coefficient(grazing))
    peaks = {}
    for name, tau in (("D", direct), ("S", surface), ("B", bottom)):
        window = np.abs(t - tau) < 4 / sc.waveform.fs
        pr = metrics.point_response(rc.data[0, 0][window], t[window])
        assert abs(pr.location - tau) * sc.waveform.fs < 1 / 20, name
        peaks[name] = pr.peak * np.exp(2j * np.pi * sc.waveform.f0 * tau)  # the carrier of its delay removed
    # -1 twice; the peaks' refinement (upsampled by 8) leaves 0.035 of scalloping between two delays
    assert abs(peaks["S"] / peaks["D"] + 2) < 0.06
    assert abs(peaks["B"] / peaks["D"] - 2 * v_bottom) < 0.06


def test_multipath_kernel_matches_reference(opencl_device):
    """Second-order multipath with a rough surface, absorption, spreading and a moving target:
    the OpenCL kernel against the float64 reference."""
    sc = shallow_scene()
    sc = sc.replace(surface=SeaSurface(0.0, rms_height=0.01),
                    targets=(PointTargets([[45.0, 3.0, -32.0], [70.0, -4.0, -10.0]], velocity=(0.5, -1.0, 0.0)),))
    common = dict(progress=False, multipath=2, spreading=True, absorption=True)
    ref = synthesize(sc, SynthesisOptions(backend="numpy", dtype=np.complex128, **common))
    got = synthesize(sc, SynthesisOptions(backend="opencl", **common))
    assert len(ref.physics.kinds) == 13
    np.testing.assert_array_equal(ref.t0, got.t0)
    assert rel_l2(got.data, ref.data) < 3e-5  # measured 2.3e-6


def test_seafloor_facets_take_no_bounce_off_the_seabed_they_lie_on(backend):
    """A facet lies on the seabed: a "bottom bounce" next to it is its direct path again (same
    delay), so those kinds are dark for facets. Before the earliest surface-bounce echo, the
    first-order echo of a seafloor patch is its direct echo alone (a doubled direct echo would
    show here), and the facets are part of the scene (scene_scatterers)."""
    sc = shallow_scene().replace(targets=())
    plain = simulate(sc, backend=backend, progress=False, multipath=0, absorption=False, spreading=False)
    first = simulate(sc, backend=backend, progress=False, multipath=1, absorption=False, spreading=False)
    assert first.provenance["paths"] == ["D-D", "D-S", "S-D"]  # the bottom bounces, dark for every facet, pruned
    assert [k.name for k in path_kinds(boundaries(sc), 1)] == ["D-D", "D-S", "D-B", "S-D", "B-D"]
    assert plain.provenance["n_scatterers"] == first.provenance["n_scatterers"] > 100
    patch = np.array([150.15, 0.0, -50.0])
    tx = sc.tx_position(sc.eta)
    surface_delay = np.min(np.linalg.norm(patch - tx * [1, 1, -1], axis=-1)
                           + np.linalg.norm(patch - tx, axis=-1)) / 1500.0  # S-D, the earliest bounce
    np.testing.assert_array_equal(first.t0, plain.t0)  # the surface paths only lengthen the window
    for h in range(sc.n_receivers):
        t = plain.fast_time(h)
        early = t < surface_delay - 0.6 * sc.waveform.duration
        assert np.count_nonzero(np.abs(plain.data[h][:, early]) > 0) > 100
        got = first.data[h][:, :plain.n_samples]
        np.testing.assert_allclose(got[:, early], plain.data[h][:, early], rtol=0, atol=1e-6)


def test_points_laid_on_the_seabed_take_no_bounce_next_to_it():
    """A point on the seabed's mean plane (as the DPCA scene lays its points) is "on the floor"
    like the facets; one 5 m above it is not."""
    from clsas.synthesis.echo.physics import on_floor

    sc = shallow_scene().replace(targets=(PointTargets([[40.0, 0.0, -50.0], [40.0, 0.0, -45.0]]),))
    kinds = path_kinds(boundaries(sc), 1)
    assert on_floor(sc.targets[0].scatterers(), None, kinds).tolist() == [True, False]
    assert [k.name for k in kinds if any(leg.planes and leg.planes[-1].law == 2 for leg in (k.out, k.back))] == \
        ["D-B", "B-D"]
