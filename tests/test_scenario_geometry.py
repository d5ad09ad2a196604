"""Scenario geometry: platform motion, attitude, receiver positions, the D/2 sampling rule."""

from __future__ import annotations

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
    Sonobuoy,
    phase_centre_gap,
)

from _small_scenario import field_pattern, small_scenario


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
    with pytest.raises(ValueError, match=field_pattern("Platform.sway")):
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
    with pytest.raises(ValueError, match=field_pattern("Platform.sway")):
        p.position(t)
    with pytest.raises(ValueError, match=field_pattern("Platform.pitch")):
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
    s = small_scenario(array=arr, sonobuoys=buoys, platform=plat)
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
    s = small_scenario(sonobuoys=(Sonobuoy((0.0, 0.0, 0.0), name="C"),))
    with pytest.raises(ValueError, match="receiver index"):
        s.receiver_position(index, 0.0)


def test_scenario_sonobuoys_only():
    s = small_scenario(array=Array(np.zeros((0, 3)), tx_length=0.1), sonobuoys=[Sonobuoy((1.0, 2.0, 3.0))])
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
        small_scenario(schedule=PulseSchedule(prf=prf, n_pulses=4))


def test_sampling_warning_uses_shortest_nonzero_element():
    # rx elements 0.1 m but transmitter 0.06 m: D/2 = 0.03 m < gap 0.05 m.
    arr = Array.uniform_line(4, 0.1, first=0.1, tx_length=0.06, rx_length=0.1)
    with pytest.warns(SamplingWarning):
        small_scenario(array=arr)


@pytest.mark.parametrize("prf", [5.0, 6.0, 10.0, 50.0])
def test_no_sampling_warning_when_well_sampled(prf):
    with warnings.catch_warnings():
        warnings.simplefilter("error", SamplingWarning)
        s = small_scenario(schedule=PulseSchedule(prf=prf, n_pulses=4))
    assert phase_centre_gap(s.array, s.platform.speed / prf) <= 0.05 + 1e-12


def test_no_sampling_warning_for_omnidirectional_elements():
    arr = Array.uniform_line(4, 0.1, first=0.1, rx_length=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SamplingWarning)
        small_scenario(array=arr, schedule=PulseSchedule(prf=0.5, n_pulses=4))


def test_replace_revalidates():
    with warnings.catch_warnings():
        warnings.simplefilter("error", SamplingWarning)
        s = small_scenario()
        s2 = s.replace(medium=Medium(1480.0))
    assert s2.medium.sound_speed == 1480.0 and s.medium.sound_speed == 1500.0
    assert s2.array is s.array
    with pytest.raises(TypeError, match=field_pattern("Scenario.medium")):
        s.replace(medium=1480.0)
    with pytest.raises(ValueError, match="no receivers"):
        s.replace(array=Array(np.zeros((0, 3))))
    with pytest.raises(ValueError, match=field_pattern("Recording.t0")):
        s.replace(recording=Recording(t0=[0.0, 0.1], n_samples=8))
    with pytest.warns(SamplingWarning):
        s.replace(schedule=PulseSchedule(prf=2.0, n_pulses=4))


def test_recording_accepts_negative_start():
    # fast time runs from the centre of the transmitted pulse: a close echo starts before 0
    rec = Recording(t0=-0.001, n_samples=10)
    assert rec.t0[0] == -0.001
