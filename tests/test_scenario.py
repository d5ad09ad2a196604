"""Scenario dataclasses: validation, derived values, geometry, attitude, sampling rule."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from clsas.scene.scenario import (
    Array,
    Medium,
    Platform,
    PulseSchedule,
    Recording,
    SamplingWarning,
    Scenario,
    Sonobuoy,
    Waveform,
    phase_centre_gap,
)

NAN, INF = float("nan"), float("inf")


def _field(name: str) -> str:
    return re.escape(name)


def _wave(**kw):
    args = dict(f0=100e3, bandwidth=20e3, duration=2e-3, fs=25e3)
    args.update(kw)
    return Waveform(**args)


def _scenario(**kw):
    """A small, well-sampled scenario: 4 hydrophones 0.1 m apart, step V/PRF = 0.2 m = 4 x D/2."""
    args = dict(
        medium=Medium(1500.0),
        waveform=_wave(),
        platform=Platform(speed=1.0, start=(1.0, 2.0, -3.0)),
        array=Array.uniform_line(4, 0.1, first=0.1, rx_length=0.1),
        schedule=PulseSchedule(prf=5.0, n_pulses=8),
    )
    args.update(kw)
    return Scenario(**args)


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize("value, exc", [
    (NAN, ValueError), (INF, ValueError), (-1500.0, ValueError), (0.0, ValueError),
    (999.0, ValueError), (2001.0, ValueError), ("1500", TypeError), (True, TypeError), (None, TypeError),
])
def test_medium_sound_speed_rejected(value, exc):
    with pytest.raises(exc, match=_field("Medium.sound_speed")):
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
    with pytest.raises(exc, match=_field(f"Waveform.{field}")):
        _wave(**{field: value})


def test_waveform_bandwidth_just_below_twice_carrier_and_fs_equal_bandwidth_accepted():
    w = Waveform(f0=100e3, bandwidth=199e3, duration=1e-3, fs=199e3)
    assert w.bandwidth == 199e3 and w.fs == 199e3


@pytest.mark.parametrize("sign", [1, -1])
def test_waveform_derived_values(sign):
    w = _wave(chirp_sign=sign)
    assert w.chirp_rate == pytest.approx(sign * 20e3 / 2e-3, rel=1e-15)
    assert w.time_bandwidth == pytest.approx(40.0, rel=1e-15)
    assert w.wavelength(Medium(1500.0)) == pytest.approx(0.015, rel=1e-15)
    assert w.wavelength(Medium(1480.0)) == pytest.approx(0.0148, rel=1e-15)


@pytest.mark.parametrize("sign", [1, -1])
def test_waveform_baseband_is_rect_times_quadratic_phase(sign):
    w = _wave(chirp_sign=sign)
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
    with pytest.raises(exc, match=_field(field)):
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
    with pytest.raises(exc, match=_field(field)):
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
    with pytest.raises(exc, match=_field(field)):
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
    with pytest.raises(exc, match=_field(field)):
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
    with pytest.raises(exc, match=_field(field)):
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
    with pytest.raises(exc, match=_field(field)):
        Recording(**kw)


def test_recording_for_receivers():
    t0, n = Recording(t0=0.1, n_samples=100).for_receivers(3)
    np.testing.assert_array_equal(t0, [0.1, 0.1, 0.1])
    np.testing.assert_array_equal(n, [100, 100, 100])
    assert n.dtype == np.int64
    t0, n = Recording(t0=[0.1, 0.2], n_samples=[5, 6]).for_receivers(2)
    np.testing.assert_array_equal(t0, [0.1, 0.2])
    np.testing.assert_array_equal(n, [5, 6])
    with pytest.raises(ValueError, match=_field("Recording.t0")):
        Recording(t0=[0.1, 0.2], n_samples=5).for_receivers(3)
    with pytest.raises(ValueError, match=_field("Recording.n_samples")):
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
    with pytest.raises(exc, match=_field(field)):
        _scenario(**kw)


def test_frozen():
    s = _scenario()
    with pytest.raises(AttributeError):
        s.medium = Medium(1480.0)
    with pytest.raises(AttributeError):
        s.waveform.f0 = 1.0
    with pytest.raises(AttributeError):
        s.platform.speed = 3.0


# --------------------------------------------------------------------------- platform motion


def test_platform_straight_track_vectorised():
    start = np.array([10.0, -5.0, -20.0])
    p = Platform(speed=2.5, start=start)
    t = np.linspace(-3.0, 7.0, 12).reshape(3, 4)
    pos = p.position(t)
    assert pos.shape == (3, 4, 3)
    expected = start + np.stack([np.zeros_like(t), 2.5 * t, np.zeros_like(t)], axis=-1)
    np.testing.assert_allclose(pos, expected, rtol=0, atol=1e-12)
    assert p.position(2.0).shape == (3,)
    np.testing.assert_allclose(p.position(2.0), [10.0, 0.0, -20.0], atol=1e-12)
    # No attitude error: identity rotation, offsets simply added.
    np.testing.assert_allclose(p.rotation(t), np.broadcast_to(np.eye(3), (3, 4, 3, 3)), atol=0)
    np.testing.assert_allclose(p.locate((0.3, -1.0, 0.2), t), expected + [0.3, -1.0, 0.2], atol=1e-12)


def test_platform_motion_errors_as_callables():
    p = Platform(
        speed=1.5, start=(1.0, 2.0, 3.0),
        surge=lambda t: 0.01 * t ** 2,
        sway=lambda t: 0.2 * np.sin(t),
        heave=lambda t: -0.05 * np.cos(2 * t),
        yaw=None,
        pitch=lambda t: 0.01,  # a constant (scalar) error
    )
    t = np.array([-1.0, 0.0, 0.5, 2.0, 4.0])
    pos = p.position(t)
    np.testing.assert_allclose(pos[:, 0], 1.0 + 0.2 * np.sin(t), atol=1e-14)
    np.testing.assert_allclose(pos[:, 1], 2.0 + 1.5 * t + 0.01 * t ** 2, atol=1e-14)
    np.testing.assert_allclose(pos[:, 2], 3.0 - 0.05 * np.cos(2 * t), atol=1e-14)
    np.testing.assert_allclose(p.motion_error("pitch", t), np.full(5, 0.01))
    np.testing.assert_array_equal(p.motion_error("yaw", t), np.zeros(5))
    with pytest.raises(ValueError, match="component"):
        p.motion_error("roll", t)


@pytest.mark.parametrize("bad", [lambda t: np.zeros(3), lambda t: np.full_like(t, np.nan)])
def test_platform_callable_bad_output_names_component(bad):
    p = Platform(speed=1.0, sway=bad)
    with pytest.raises(ValueError, match=_field("Platform.sway")):
        p.position(np.linspace(0.0, 1.0, 5))


def test_platform_motion_errors_as_sampled_arrays_interpolated():
    times = np.linspace(0.0, 10.0, 11)
    cubic = lambda t: 1e-3 * (t ** 3 - 4 * t ** 2 + 2 * t - 1)  # noqa: E731
    p = Platform(speed=2.0, sway=cubic(times), heave=0.1 * times, yaw=np.full(11, 0.02), error_times=times)
    assert p.error_times.flags.writeable is False
    tq = np.array([[0.0, 0.25, 3.7], [5.5, 9.99, 10.0]])
    # A cubic spline (not-a-knot) reproduces a cubic polynomial exactly, and a line and a constant.
    np.testing.assert_allclose(p.motion_error("sway", tq), cubic(tq), rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.motion_error("heave", tq), 0.1 * tq, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.motion_error("yaw", tq), 0.02, rtol=0, atol=1e-14)
    pos = p.position(tq)
    assert pos.shape == (2, 3, 3)
    np.testing.assert_allclose(pos[..., 0], cubic(tq), atol=1e-12)
    np.testing.assert_allclose(pos[..., 1], 2.0 * tq, atol=1e-12)
    np.testing.assert_allclose(pos[..., 2], 0.1 * tq, atol=1e-12)
    # Sample points are reproduced.
    np.testing.assert_allclose(p.motion_error("sway", times), cubic(times), atol=1e-15)


@pytest.mark.parametrize("t", [-0.01, 10.01, np.array([1.0, 11.0]), np.array([-5.0, 5.0])])
def test_platform_sampled_errors_outside_range_raise(t):
    times = np.linspace(0.0, 10.0, 11)
    p = Platform(speed=2.0, sway=np.zeros(11), pitch=np.zeros(11), error_times=times)
    with pytest.raises(ValueError, match=_field("Platform.sway")):
        p.position(t)
    with pytest.raises(ValueError, match=_field("Platform.pitch")):
        p.rotation(t)
    # Components not sampled are defined everywhere.
    np.testing.assert_array_equal(p.motion_error("surge", t), np.zeros_like(np.asarray(t, float)))


# --------------------------------------------------------------------------- attitude


@pytest.mark.parametrize("psi", [0.0, 0.02, -0.03, np.deg2rad(2.0), np.pi / 2])
def test_yaw_turns_bow_towards_plus_x(psi):
    """Docstring: positive yaw turns +y_b towards +x; body (0, d, 0) -> world (d sin psi, d cos psi, 0)."""
    d = 1.28
    p = Platform(speed=1.0, start=(5.0, 0.0, -10.0), yaw=lambda t: np.full_like(t, psi))
    t = np.array([0.0, 1.0, 2.5])
    world = p.locate((0.0, d, 0.0), t) - p.position(t)
    np.testing.assert_allclose(world, np.broadcast_to([d * np.sin(psi), d * np.cos(psi), 0.0], (3, 3)), atol=1e-14)
    if psi > 0:
        assert np.all(world[:, 0] > 0)
    # Clockwise seen from above: an across-track offset (+x_b) turns towards -y.
    side = p.locate((1.0, 0.0, 0.0), 0.0) - p.position(0.0)
    np.testing.assert_allclose(side, [np.cos(psi), -np.sin(psi), 0.0], atol=1e-14)


@pytest.mark.parametrize("theta", [0.0, 0.02, -0.03, np.pi / 2])
def test_pitch_raises_bow(theta):
    d = 0.5
    p = Platform(speed=1.0, pitch=lambda t: np.full_like(t, theta))
    world = p.locate((0.0, d, 0.0), 0.0) - p.position(0.0)
    np.testing.assert_allclose(world, [0.0, d * np.cos(theta), d * np.sin(theta)], atol=1e-14)


def test_yaw_and_pitch_match_wu2018_hydrophone_position():
    """Wu et al. 2018 eqs. 2-3: (d cos(pitch) sin(yaw), d cos(pitch) cos(yaw), d sin(pitch))."""
    d, psi, theta = 0.96, np.deg2rad(1.5), np.deg2rad(-1.2)
    p = Platform(speed=3.0, yaw=lambda t: np.full_like(t, psi), pitch=lambda t: np.full_like(t, theta))
    world = p.locate((0.0, d, 0.0), 0.7) - p.position(0.7)
    expected = [d * np.cos(theta) * np.sin(psi), d * np.cos(theta) * np.cos(psi), d * np.sin(theta)]
    np.testing.assert_allclose(world, expected, atol=1e-14)
    # Attitude rotates offsets about the reference point, never the reference point itself.
    np.testing.assert_allclose(p.locate((0.0, 0.0, 0.0), 0.7), p.position(0.7), atol=0)


def test_rotation_matrices_orthonormal_det_plus_one(rng):
    t = np.linspace(0.0, 5.0, 24).reshape(4, 6)
    p = Platform(speed=1.0, yaw=lambda t: 0.3 * np.sin(3 * t), pitch=lambda t: -0.2 * np.cos(t))
    r = p.rotation(t)
    assert r.shape == (4, 6, 3, 3)
    eye = np.broadcast_to(np.eye(3), r.shape)
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), eye, atol=1e-14)
    np.testing.assert_allclose(np.swapaxes(r, -1, -2) @ r, eye, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-14)
    # locate() agrees with the matrices, and preserves the offset's length.
    off = rng.normal(size=3)
    loc = p.locate(off, t) - p.position(t)
    np.testing.assert_allclose(loc, np.einsum("...ij,j->...i", r, off), atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(loc, axis=-1), np.linalg.norm(off), atol=1e-14)


# --------------------------------------------------------------------------- scenario geometry


def test_scenario_receiver_positions_hydrophones_and_stationary_sonobuoys():
    arr = Array.uniform_line(3, 0.2, first=-0.2, tx_along=0.05, rx_length=0.0, names=("a", "b", "c"))
    buoys = (Sonobuoy((-500.0, 0.0, -150.0), name="C"), Sonobuoy((30.0, 40.0, -5.0), name="D"))
    plat = Platform(speed=3.0, start=(1.0, 2.0, -43.0), yaw=lambda t: 0.01 * t)
    s = _scenario(array=arr, sonobuoys=buoys, platform=plat)
    assert s.n_receivers == 5
    assert s.receiver_names == ("a", "b", "c", "C", "D")
    t = np.array([[-1.0, 0.0], [0.5, 3.0]])
    pos = s.rx_positions(t)
    assert pos.shape == (5, 2, 2, 3)
    for i in range(3):
        np.testing.assert_allclose(pos[i], plat.locate(arr.rx_offsets[i], t), atol=1e-12)
        np.testing.assert_allclose(s.receiver_position(i, t), pos[i], atol=0)
    # Hydrophone 1 sits on the reference point: it follows the straight track exactly.
    np.testing.assert_allclose(pos[1], np.stack([np.full_like(t, 1.0), 2.0 + 3.0 * t, np.full_like(t, -43.0)], -1),
                               atol=1e-12)
    np.testing.assert_allclose(pos[3], np.broadcast_to([-500.0, 0.0, -150.0], (2, 2, 3)), atol=0)
    np.testing.assert_allclose(pos[4], np.broadcast_to([30.0, 40.0, -5.0], (2, 2, 3)), atol=0)
    np.testing.assert_allclose(s.receiver_position(np.int64(3), 7.0), [-500.0, 0.0, -150.0])
    # Transmitter at emission.
    np.testing.assert_allclose(s.tx_position(s.eta), plat.locate((0.0, 0.05, 0.0), s.eta), atol=1e-12)
    np.testing.assert_allclose(s.eta, s.schedule.eta)


@pytest.mark.parametrize("index", [-1, 5, 2.0, True, "0"])
def test_scenario_receiver_index_rejected(index):
    s = _scenario(sonobuoys=(Sonobuoy((0.0, 0.0, 0.0), name="C"),))
    with pytest.raises(ValueError, match="receiver index"):
        s.receiver_position(index, 0.0)


def test_scenario_sonobuoys_only():
    s = _scenario(array=Array(np.zeros((0, 3)), tx_length=0.1), sonobuoys=[Sonobuoy((1.0, 2.0, 3.0))])
    assert isinstance(s.sonobuoys, tuple)
    assert s.n_receivers == 1 and s.receiver_names == ("buoy",)
    assert s.rx_positions(np.zeros(4)).shape == (1, 4, 3)


# --------------------------------------------------------------------------- D/2 sampling rule


def test_phase_centre_gap():
    a = Array.uniform_line(4, 0.1, first=0.1)  # phase centres 0.05 apart, 0.05..0.2
    assert phase_centre_gap(a, 0.2) == pytest.approx(0.05)
    assert phase_centre_gap(a, 0.3) == pytest.approx(0.15)   # 0.3 - 3 x 0.05
    assert phase_centre_gap(a, 0.1) == pytest.approx(0.05)   # overlapping centres
    b = Array.uniform_line(3, 0.1, first=0.0, tx_along=0.1)  # centres 0.05, 0.1, 0.15
    assert phase_centre_gap(b, 0.4) == pytest.approx(0.3)    # wrap-around gap 0.4 - 0.1
    single = Array([[0.0, 0.3, 0.0]])
    assert phase_centre_gap(single, 0.7) == pytest.approx(0.7)


@pytest.mark.parametrize("prf", [4.0, 2.0, 4.9])
def test_sampling_warning_when_gap_exceeds_half_element(prf):
    # step V/PRF > 0.2 m: gap = step - 0.15 m > D/2 = 0.05 m.
    with pytest.warns(SamplingWarning, match="D/2"):
        _scenario(schedule=PulseSchedule(prf=prf, n_pulses=4))


def test_sampling_warning_uses_shortest_nonzero_element():
    # rx elements 0.1 m but transmitter 0.06 m: D/2 = 0.03 m < gap 0.05 m.
    arr = Array.uniform_line(4, 0.1, first=0.1, tx_length=0.06, rx_length=0.1)
    with pytest.warns(SamplingWarning):
        _scenario(array=arr)


@pytest.mark.parametrize("prf", [5.0, 6.0, 10.0, 50.0])
def test_no_sampling_warning_when_well_sampled(prf):
    with warnings.catch_warnings():
        warnings.simplefilter("error", SamplingWarning)
        s = _scenario(schedule=PulseSchedule(prf=prf, n_pulses=4))
    assert phase_centre_gap(s.array, s.platform.speed / prf) <= 0.05 + 1e-12


def test_no_sampling_warning_for_omnidirectional_elements():
    arr = Array.uniform_line(4, 0.1, first=0.1, rx_length=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SamplingWarning)
        _scenario(array=arr, schedule=PulseSchedule(prf=0.5, n_pulses=4))


def test_replace_revalidates():
    with warnings.catch_warnings():
        warnings.simplefilter("error", SamplingWarning)
        s = _scenario()
        s2 = s.replace(medium=Medium(1480.0))
    assert s2.medium.sound_speed == 1480.0 and s.medium.sound_speed == 1500.0
    assert s2.array is s.array
    with pytest.raises(TypeError, match=_field("Scenario.medium")):
        s.replace(medium=1480.0)
    with pytest.raises(ValueError, match="no receivers"):
        s.replace(array=Array(np.zeros((0, 3))))
    with pytest.raises(ValueError, match=_field("Recording.t0")):
        s.replace(recording=Recording(t0=[0.0, 0.1], n_samples=8))
    with pytest.warns(SamplingWarning):
        s.replace(schedule=PulseSchedule(prf=2.0, n_pulses=4))


def test_recording_accepts_negative_start():
    # fast time runs from the centre of the transmitted pulse: a close echo starts before 0
    rec = Recording(t0=-0.001, n_samples=10)
    assert rec.t0[0] == -0.001
