"""Scenario dataclasses: validation and derived values (geometry and motion: test_scenario_geometry)."""

from __future__ import annotations


import numpy as np
import pytest

from clsas.scene.scenario import (
    Array,
    Medium,
    Platform,
    PulseSchedule,
    Recording,
    Sonobuoy,
    Waveform,
)

from _small_scenario import field_pattern, small_scenario, small_waveform

NAN, INF = float("nan"), float("inf")


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize("value, exc", [
    (NAN, ValueError), (INF, ValueError), (-1500.0, ValueError), (0.0, ValueError),
    (999.0, ValueError), (2001.0, ValueError), ("1500", TypeError), (True, TypeError), (None, TypeError),
])
def test_medium_sound_speed_rejected(value, exc):
    with pytest.raises(exc, match=field_pattern("Medium.sound_speed")):
        Medium(value)


def test_medium_sound_speed_accepted_at_bounds():
    assert Medium(1000).sound_speed == 1000.0
    assert Medium(2000.0).sound_speed == 2000.0
    assert isinstance(Medium(1500).sound_speed, float)


@pytest.mark.parametrize("field, value, exc", [
    ("f0", NAN, ValueError), ("f0", INF, ValueError), ("f0", -1.0, ValueError), ("f0", 0.0, ValueError),
    ("f0", "1e5", TypeError),
    ("bandwidth", NAN, ValueError), ("bandwidth", INF, ValueError), ("bandwidth", -1.0, ValueError),
    ("bandwidth", 0.0, ValueError), ("bandwidth", 200e3, ValueError), ("bandwidth", 250e3, ValueError),
    ("bandwidth", None, TypeError),
    ("duration", NAN, ValueError), ("duration", INF, ValueError), ("duration", -1e-3, ValueError),
    ("duration", 0.0, ValueError),
    ("fs", NAN, ValueError), ("fs", INF, ValueError), ("fs", -25e3, ValueError), ("fs", 19999.0, ValueError),
    ("fs", [25e3], TypeError),
    ("chirp_sign", 0, ValueError), ("chirp_sign", 2, ValueError), ("chirp_sign", NAN, ValueError),
])
def test_waveform_field_rejected(field, value, exc):
    with pytest.raises(exc, match=field_pattern(f"Waveform.{field}")):
        small_waveform(**{field: value})


def test_waveform_bandwidth_just_below_twice_carrier_and_fs_equal_bandwidth_accepted():
    w = Waveform(f0=100e3, bandwidth=199e3, duration=1e-3, fs=199e3)
    assert w.bandwidth == 199e3 and w.fs == 199e3


@pytest.mark.parametrize("sign", [1, -1])
def test_waveform_derived_values(sign):
    w = small_waveform(chirp_sign=sign)
    assert w.chirp_rate == pytest.approx(sign * 20e3 / 2e-3, rel=1e-15)
    assert w.time_bandwidth == pytest.approx(40.0, rel=1e-15)
    assert w.wavelength(Medium(1500.0)) == pytest.approx(0.015, rel=1e-15)
    assert w.wavelength(Medium(1480.0)) == pytest.approx(0.0148, rel=1e-15)


@pytest.mark.parametrize("sign", [1, -1])
def test_waveform_baseband_is_rect_times_quadratic_phase(sign):
    w = small_waveform(chirp_sign=sign)
    T, K = w.duration, sign * w.bandwidth / w.duration
    tau = np.linspace(-T, T, 801)
    got = w.baseband(tau)
    inside = np.abs(tau) <= T / 2
    assert got.shape == tau.shape
    np.testing.assert_allclose(got[inside], np.exp(1j * np.pi * K * tau[inside] ** 2), rtol=0, atol=1e-12)
    assert np.all(got[~inside] == 0)
    # Edges are included, just outside is zero; the phase curvature has the chirp's sign.
    assert abs(w.baseband(T / 2)) == pytest.approx(1.0)
    assert w.baseband(T / 2 * (1 + 1e-9)) == 0
    t1 = 0.01 * T  # pi K t1^2 = sign 0.0001 pi B T = sign 0.004 pi: no wrap, sign of the chirp
    assert np.angle(w.baseband(t1)) == pytest.approx(sign * 0.004 * np.pi, rel=1e-9)
    phase = np.unwrap(np.angle(got[inside]))
    # Instantaneous frequency (1/2pi) d phase/d tau = K tau: a line of slope K.
    f_inst = np.gradient(phase, tau[inside]) / (2 * np.pi)
    slope = np.polyfit(tau[inside][5:-5], f_inst[5:-5], 1)[0]
    assert slope == pytest.approx(K, rel=1e-3)


@pytest.mark.parametrize("kw, field, exc", [
    (dict(speed=NAN), "Platform.speed", ValueError),
    (dict(speed=INF), "Platform.speed", ValueError),
    (dict(speed=-1.0), "Platform.speed", ValueError),
    (dict(speed=0.0), "Platform.speed", ValueError),
    (dict(speed="2"), "Platform.speed", TypeError),
    (dict(start=(0.0, NAN, 0.0)), "Platform.start", ValueError),
    (dict(start=(0.0, 0.0, INF)), "Platform.start", ValueError),
    (dict(start=(0.0, 0.0)), "Platform.start", ValueError),
    (dict(start=np.zeros((1, 3))), "Platform.start", ValueError),
    (dict(start=("a", 0, 0)), "Platform.start", TypeError),
    (dict(sway=np.zeros(4)), "Platform.error_times", ValueError),
    (dict(sway=np.zeros(4), error_times=[0.0, 1.0, 1.0, 2.0]), "Platform.error_times", ValueError),
    (dict(sway=np.zeros(4), error_times=[0.0, 2.0, 1.0, 3.0]), "Platform.error_times", ValueError),
    (dict(sway=np.zeros(1), error_times=[0.0]), "Platform.error_times", ValueError),
    (dict(sway=np.zeros(4), error_times=[0.0, 1.0, NAN, 3.0]), "Platform.error_times", ValueError),
    (dict(error_times=[0.0, 1.0]), "Platform.error_times", ValueError),
    (dict(sway=np.zeros(3), error_times=[0.0, 1.0, 2.0, 3.0]), "Platform.sway", ValueError),
    (dict(heave=np.zeros((4, 1)), error_times=[0.0, 1.0, 2.0, 3.0]), "Platform.heave", ValueError),
    (dict(yaw=[0.0, NAN, 0.0, 0.0], error_times=[0.0, 1.0, 2.0, 3.0]), "Platform.yaw", ValueError),
    (dict(pitch=[0.0, INF, 0.0, 0.0], error_times=[0.0, 1.0, 2.0, 3.0]), "Platform.pitch", ValueError),
    (dict(surge=["a", "b", "c", "d"], error_times=[0.0, 1.0, 2.0, 3.0]), "Platform.surge", TypeError),
])
def test_platform_field_rejected(kw, field, exc):
    args = dict(speed=2.0)
    args.update(kw)
    with pytest.raises(exc, match=field_pattern(field)):
        Platform(**args)


@pytest.mark.parametrize("kw, field, exc", [
    (dict(rx_offsets=np.zeros((3, 2))), "Array.rx_offsets", ValueError),
    (dict(rx_offsets=np.zeros(3)), "Array.rx_offsets", ValueError),
    (dict(rx_offsets=[[0.0, NAN, 0.0]]), "Array.rx_offsets", ValueError),
    (dict(rx_offsets=[[0.0, INF, 0.0]]), "Array.rx_offsets", ValueError),
    (dict(tx_offset=(0.0, 1.0)), "Array.tx_offset", ValueError),
    (dict(tx_offset=(0.0, NAN, 0.0)), "Array.tx_offset", ValueError),
    (dict(tx_length=-0.1), "Array.tx_length", ValueError),
    (dict(tx_length=NAN), "Array.tx_length", ValueError),
    (dict(tx_length=INF), "Array.tx_length", ValueError),
    (dict(tx_length=[0.1]), "Array.tx_length", TypeError),
    (dict(rx_length=-0.1), "Array.rx_length", ValueError),
    (dict(rx_length=NAN), "Array.rx_length", ValueError),
    (dict(rx_length=[0.1, -0.1, 0.1]), "Array.rx_length", ValueError),
    (dict(rx_length=[0.1, 0.1, INF]), "Array.rx_length", ValueError),
    pytest.param(dict(rx_length=[0.1, 0.1]), "Array.rx_length", ValueError, id="rx_length-wrong-length"),
    pytest.param(dict(rx_length=[[0.1, 0.1, 0.1]]), "Array.rx_length", ValueError, id="rx_length-wrong-ndim"),
    pytest.param(dict(rx_length="abc"), "Array.rx_length", (TypeError, ValueError), id="rx_length-not-numeric"),
    (dict(names=("a", "b")), "Array.names", ValueError),
    (dict(names=("a", "", "c")), "Array.names", ValueError),
    (dict(names=("a", 2, "c")), "Array.names", ValueError),
])
def test_array_field_rejected(kw, field, exc):
    args = dict(rx_offsets=np.zeros((3, 3)))
    args.update(kw)
    with pytest.raises(exc, match=field_pattern(field)):
        Array(**args)


def test_array_defaults_and_read_only():
    a = Array(rx_offsets=[[0.0, 1.0, 0.0], [0.0, 2.0, 0.0]], rx_length=0.05)
    assert a.n_receivers == 2
    assert a.names == ("h0", "h1")
    np.testing.assert_array_equal(a.tx_offset, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(a.rx_length, [0.05, 0.05])
    assert a.rx_offsets.dtype == np.float64
    with pytest.raises(ValueError):
        a.rx_offsets[0, 0] = 1.0  # read-only
    empty = Array(rx_offsets=np.zeros((0, 3)))
    assert empty.n_receivers == 0 and empty.names == ()


@pytest.mark.parametrize("kw, field, exc", [
    (dict(n_receivers=0), "n_receivers", ValueError),
    (dict(n_receivers=2.5), "n_receivers", TypeError),
    (dict(n_receivers=True), "n_receivers", TypeError),
    (dict(spacing=0.0), "spacing", ValueError),
    (dict(spacing=-0.1), "spacing", ValueError),
    (dict(spacing=NAN), "spacing", ValueError),
    (dict(first=INF), "first", ValueError),
    (dict(tx_along=NAN), "tx_along", ValueError),
    (dict(tx_length=-1.0), "Array.tx_length", ValueError),
])
def test_uniform_line_rejected(kw, field, exc):
    args = dict(n_receivers=4, spacing=0.1, first=0.0)
    args.update(kw)
    with pytest.raises(exc, match=field_pattern(field)):
        Array.uniform_line(**args)


def test_uniform_line_geometry():
    a = Array.uniform_line(5, 0.04, first=0.06, tx_along=-0.02, tx_length=0.08)
    assert a.n_receivers == 5
    np.testing.assert_allclose(a.rx_offsets[:, 1], 0.06 + 0.04 * np.arange(5), rtol=0, atol=1e-15)
    assert np.all(a.rx_offsets[:, [0, 2]] == 0)
    np.testing.assert_array_equal(a.tx_offset, [0.0, -0.02, 0.0])
    assert a.tx_length == 0.08
    np.testing.assert_array_equal(a.rx_length, np.full(5, 0.04))  # defaults to spacing
    assert a.names == ("h0", "h1", "h2", "h3", "h4")
    b = Array.uniform_line(3, 0.1, first=-0.1, rx_length=0.0, names=("L", "C", "R"))
    np.testing.assert_allclose(b.rx_offsets[:, 1], [-0.1, 0.0, 0.1], atol=1e-15)
    np.testing.assert_array_equal(b.rx_length, [0.0, 0.0, 0.0])
    assert b.names == ("L", "C", "R")


@pytest.mark.parametrize("kw, field, exc", [
    (dict(position=(0.0, NAN, 0.0)), "position", ValueError),
    (dict(position=(0.0, 0.0, -INF)), "position", ValueError),
    (dict(position=(0.0, 0.0)), "position", ValueError),
    (dict(position=np.zeros((2, 3))), "position", ValueError),
    (dict(position=(0.0, 0.0, 0.0), name=""), "Sonobuoy.name", ValueError),
    (dict(position=(0.0, 0.0, 0.0), name=3), "Sonobuoy.name", ValueError),
])
def test_sonobuoy_field_rejected(kw, field, exc):
    with pytest.raises(exc, match=field_pattern(field)):
        Sonobuoy(**kw)


def test_sonobuoy_position_error_names_the_buoy():
    with pytest.raises(ValueError, match=r"Sonobuoy\('C'\)\.position"):
        Sonobuoy((NAN, 0.0, 0.0), name="C")


@pytest.mark.parametrize("kw, field, exc", [
    (dict(prf=NAN, n_pulses=4), "PulseSchedule.prf", ValueError),
    (dict(prf=INF, n_pulses=4), "PulseSchedule.prf", ValueError),
    (dict(prf=-5.0, n_pulses=4), "PulseSchedule.prf", ValueError),
    (dict(prf=0.0, n_pulses=4), "PulseSchedule.prf", ValueError),
    (dict(prf=5.0, n_pulses=0), "PulseSchedule.n_pulses", ValueError),
    (dict(prf=5.0, n_pulses=-3), "PulseSchedule.n_pulses", ValueError),
    (dict(prf=5.0, n_pulses=2.5), "PulseSchedule.n_pulses", TypeError),
    (dict(prf=5.0, n_pulses=True), "PulseSchedule.n_pulses", TypeError),
    (dict(prf=5.0, exposure=NAN), "PulseSchedule.exposure", ValueError),
    (dict(prf=5.0, exposure=INF), "PulseSchedule.exposure", ValueError),
    (dict(prf=5.0, exposure=-1.0), "PulseSchedule.exposure", ValueError),
    (dict(prf=5.0, exposure=0.1), "PulseSchedule.exposure", ValueError),  # < 1/prf: no pulse
    (dict(prf=5.0, n_pulses=4, start=NAN), "PulseSchedule.start", ValueError),
    (dict(prf=5.0, n_pulses=4, start=INF), "PulseSchedule.start", ValueError),
    (dict(prf=5.0), "n_pulses", ValueError),                                # neither
    (dict(prf=5.0, n_pulses=4, exposure=1.0), "exposure", ValueError),     # both
])
def test_pulse_schedule_rejected(kw, field, exc):
    with pytest.raises(exc, match=field_pattern(field)):
        PulseSchedule(**kw)


def test_pulse_schedule_eta_centred_spacing_one_over_prf():
    s = PulseSchedule(prf=4.0, n_pulses=9)
    eta = s.eta
    assert eta.shape == (9,)
    np.testing.assert_allclose(np.diff(eta), 0.25, rtol=0, atol=1e-15)
    assert eta.mean() == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(eta[[0, -1]], [-1.0, 1.0], atol=1e-15)
    even = PulseSchedule(prf=10.0, n_pulses=4).eta
    np.testing.assert_allclose(even, [-0.15, -0.05, 0.05, 0.15], atol=1e-15)


def test_pulse_schedule_start_and_exposure():
    s = PulseSchedule(prf=3.0, n_pulses=4, start=2.0)
    np.testing.assert_allclose(s.eta, 2.0 + np.arange(4) / 3.0, atol=1e-15)
    # exposure -> floor(exposure prf) pulses, robust to rounding of exposure * prf.
    assert PulseSchedule(prf=80.0, exposure=80.0).n_pulses == 6400
    assert PulseSchedule(prf=10.0, exposure=0.3).n_pulses == 3
    assert PulseSchedule(prf=10.0, exposure=0.7).n_pulses == 7
    assert PulseSchedule(prf=10.0, exposure=0.79).n_pulses == 7
    assert PulseSchedule(prf=5.0, exposure=0.2).n_pulses == 1
    e = PulseSchedule(prf=10.0, exposure=0.7).eta
    np.testing.assert_allclose(np.diff(e), 0.1, atol=1e-15)
    assert e.mean() == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize("kw, field, exc", [
    (dict(t0=NAN, n_samples=10), "Recording.t0", ValueError),
    (dict(t0=[0.0, INF], n_samples=10), "Recording.t0", ValueError),
    (dict(t0=[[0.0, 0.1]], n_samples=10), "Recording.t0", ValueError),
    (dict(t0=0.0, n_samples=0), "Recording.n_samples", ValueError),
    (dict(t0=0.0, n_samples=[10, -1]), "Recording.n_samples", ValueError),
    (dict(t0=0.0, n_samples=10.5), "Recording.n_samples", TypeError),
    (dict(t0=0.0, n_samples=[[10, 10]]), "Recording.n_samples", ValueError),
    (dict(t0=0.0, n_samples="10"), "Recording.n_samples", TypeError),
])
def test_recording_rejected(kw, field, exc):
    with pytest.raises(exc, match=field_pattern(field)):
        Recording(**kw)


def test_recording_for_receivers():
    t0, n = Recording(t0=0.1, n_samples=100).for_receivers(3)
    np.testing.assert_array_equal(t0, [0.1, 0.1, 0.1])
    np.testing.assert_array_equal(n, [100, 100, 100])
    assert n.dtype == np.int64
    t0, n = Recording(t0=[0.1, 0.2], n_samples=[5, 6]).for_receivers(2)
    np.testing.assert_array_equal(t0, [0.1, 0.2])
    np.testing.assert_array_equal(n, [5, 6])
    with pytest.raises(ValueError, match=field_pattern("Recording.t0")):
        Recording(t0=[0.1, 0.2], n_samples=5).for_receivers(3)
    with pytest.raises(ValueError, match=field_pattern("Recording.n_samples")):
        Recording(t0=0.1, n_samples=[5, 6]).for_receivers(3)


@pytest.mark.parametrize("kw, field, exc", [
    (dict(medium=1500.0), "Scenario.medium", TypeError),
    (dict(waveform=None), "Scenario.waveform", TypeError),
    (dict(platform="p"), "Scenario.platform", TypeError),
    (dict(array=np.zeros((3, 3))), "Scenario.array", TypeError),
    (dict(schedule=5.0), "Scenario.schedule", TypeError),
    (dict(sonobuoys=((0.0, 0.0, 0.0),)), "Scenario.sonobuoys", TypeError),
    (dict(recording=(0.0, 10)), "Scenario.recording", TypeError),
    (dict(recording=Recording(t0=[0.0, 0.1], n_samples=10)), "Recording.t0", ValueError),
    (dict(array=Array(np.zeros((0, 3)))), "no receivers", ValueError),
    (dict(sonobuoys=(Sonobuoy((0.0, 0.0, 0.0), name="h1"),)), "unique", ValueError),
    (dict(sonobuoys=(Sonobuoy((0.0, 0.0, 0.0)), Sonobuoy((1.0, 0.0, 0.0)))), "unique", ValueError),
])
def test_scenario_rejected(kw, field, exc):
    with pytest.raises(exc, match=field_pattern(field)):
        small_scenario(**kw)


def test_frozen():
    s = small_scenario()
    with pytest.raises(AttributeError):
        s.medium = Medium(1480.0)
    with pytest.raises(AttributeError):
        s.waveform.f0 = 1.0
    with pytest.raises(AttributeError):
        s.platform.speed = 3.0

