"""The papers' sonars by name: each constructs and carries the numbers its docstring cites."""

from __future__ import annotations

import inspect
import re
import warnings

import numpy as np
import pytest

from clsas.scene import presets
from clsas.scene.scenario import SamplingWarning, Scenario, Sonobuoy, phase_centre_gap

# Presets whose docstring says the printed parameters undersample the aperture.
DOCUMENTED_TO_WARN = {"zhang2019"}


def _build(name, **options):
    """Construct a preset, expecting a SamplingWarning only where its docstring says so."""
    if name in DOCUMENTED_TO_WARN:
        with pytest.warns(SamplingWarning):
            return presets.sonar(name, **options)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SamplingWarning)
        return presets.sonar(name, **options)


def _step(s: Scenario) -> float:
    return s.platform.speed / s.schedule.prf


def test_registry_lists_the_five_papers():
    assert set(presets.SONARS) == {"kiang2022", "huang2022", "wu2018", "zhang2019", "heremans2009"}
    for name, fn in presets.SONARS.items():
        assert fn is getattr(presets, name)
        assert f"``{name}``" in presets.__doc__


@pytest.mark.parametrize("name", sorted(presets.SONARS))
def test_preset_constructs_with_small_n_pulses(name):
    assert "n_pulses" in inspect.signature(presets.SONARS[name]).parameters
    s = _build(name, n_pulses=6)
    assert isinstance(s, Scenario)
    assert s.schedule.n_pulses == 6
    eta = s.eta
    np.testing.assert_allclose(np.diff(eta), 1 / s.schedule.prf, rtol=1e-12)
    assert eta.mean() == pytest.approx(0.0, abs=1e-12)
    assert s.n_receivers == len(s.receiver_names) >= 1
    assert s.rx_positions(eta[:2]).shape == (s.n_receivers, 2, 3)


@pytest.mark.parametrize("name", sorted(presets.SONARS))
def test_preset_sampling_warning_matches_docstring(name):
    """Only the presets documented as undersampled may warn, and the D/2 rule agrees."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s = presets.sonar(name, n_pulses=4)
    warned = [w for w in caught if issubclass(w.category, SamplingWarning)]
    lengths = np.concatenate([[s.array.tx_length], s.array.rx_length])
    nonzero = lengths[lengths > 0]
    if nonzero.size:
        gap, limit = phase_centre_gap(s.array, _step(s)), nonzero.min() / 2
        if name in DOCUMENTED_TO_WARN:
            assert gap > limit
        else:
            assert gap <= limit * (1 + 1e-9), (
                f"{name}: phase-centre gap {gap * 1e3:.3f} mm exceeds D/2 = {limit * 1e3:.3f} mm "
                f"(V/PRF = {_step(s) * 1e3:.3f} mm)")
    assert bool(warned) == (name in DOCUMENTED_TO_WARN), [str(w.message) for w in warned]


def test_sonar_by_name_and_default():
    s = presets.sonar("huang2022", n_pulses=3)
    assert s.array.n_receivers == 32 and s.schedule.n_pulses == 3
    d = presets.sonar()
    assert d.receiver_names == ("A", "B", "C")  # the default is kiang2022


@pytest.mark.parametrize("bad", ["nope", "Kiang2022", "", "huang"])
def test_unknown_name_lists_known_names(bad):
    with pytest.raises(ValueError) as info:
        presets.sonar(bad)
    msg = str(info.value)
    assert repr(bad) in msg
    for known in presets.SONARS:
        assert known in msg


def test_unknown_option_is_refused():
    with pytest.raises(TypeError):
        presets.sonar("huang2022", n_pulse=3)


# --------------------------------------------------------------------------- kiang2022


def test_kiang2022_table_i():
    s = _build("kiang2022")  # the full 80 s exposure: schedule only, nothing allocated
    assert s.medium.sound_speed == 1500.0
    assert s.platform.speed == 3.0
    w = s.waveform
    assert (w.f0, w.bandwidth, w.duration, w.fs) == (150e3, 20e3, 5e-3, 20e3)
    assert w.chirp_rate == pytest.approx(4e6)  # K_r = 4 MHz/s
    assert s.schedule.prf == 80.0
    assert s.schedule.n_pulses == 6400  # T_a = 80 s at 80 Hz
    assert s.eta.mean() == pytest.approx(0.0, abs=1e-9)
    assert s.eta[-1] - s.eta[0] == pytest.approx(6399 / 80.0)
    assert presets.kiang2022(n_pulses=10).schedule.prf == 80.0


def test_kiang2022_receivers_a_b_c():
    s = _build("kiang2022", n_pulses=8)
    assert s.receiver_names == ("A", "B", "C")
    assert s.array.n_receivers == 2 and len(s.sonobuoys) == 1
    assert isinstance(s.sonobuoys[0], Sonobuoy) and s.sonobuoys[0].name == "C"
    depth = s.platform.start[2]  # -L1 sin(theta_b) with L1 = 250 m, theta_b = 10 deg
    assert depth == pytest.approx(-43.41, abs=0.01)
    np.testing.assert_array_equal(s.platform.start[:2], [0.0, 0.0])
    eta = np.array([-10.0, -0.5, 0.0, 3.0, 40.0])
    zeros = np.zeros_like(eta)
    a = s.receiver_position(0, eta)
    b = s.receiver_position(1, eta)
    c = s.receiver_position(2, eta)
    np.testing.assert_allclose(a, np.stack([zeros, 3.0 * eta, zeros + depth], -1), atol=1e-12)
    np.testing.assert_allclose(b, np.stack([zeros, 3.0 * eta - 250.0, zeros + depth], -1), atol=1e-12)
    np.testing.assert_allclose(c, np.broadcast_to([-500.0, 0.0, -150.0], (5, 3)), atol=0)  # stationary
    # A is the transceiver: the transmitter is at A.
    np.testing.assert_allclose(s.tx_position(eta), a, atol=0)
    # Omnidirectional (assumed): no element lengths.
    assert s.array.tx_length == 0 and np.all(s.array.rx_length == 0)


# --------------------------------------------------------------------------- huang2022


def test_huang2022_table_1():
    s = _build("huang2022", n_pulses=4)
    a = s.array
    assert a.n_receivers == 32
    np.testing.assert_allclose(a.rx_offsets[:, 1], 0.06 + 0.04 * np.arange(32), atol=1e-12)
    assert np.all(a.rx_offsets[:, [0, 2]] == 0)
    np.testing.assert_array_equal(a.tx_offset, [0.0, 0.0, 0.0])
    array_length = a.rx_offsets[-1, 1] + a.rx_length[-1] / 2 - (a.rx_offsets[0, 1] - a.rx_length[0] / 2)
    assert array_length == pytest.approx(1.28)  # 32 contiguous elements of 0.04 m
    np.testing.assert_allclose(a.rx_length, 0.04)
    assert a.tx_length == 0.08
    assert s.platform.speed == 2.0
    assert 1 / s.schedule.prf == pytest.approx(0.32)
    w = s.waveform
    assert (w.f0, w.bandwidth) == (150e3, 20e3)
    assert _step(s) == pytest.approx(0.64)
    assert phase_centre_gap(a, _step(s)) == pytest.approx(0.02)  # = D_rx / 2: critically sampled
    assert presets.huang2022.__defaults__ == (256,)


# --------------------------------------------------------------------------- wu2018


def test_wu2018_table_1():
    # The SamplingWarning question is tested above; here only the table's numbers.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SamplingWarning)
        s = presets.wu2018(n_pulses=4)
    a = s.array
    assert a.n_receivers == 32
    np.testing.assert_allclose(a.rx_offsets[:, 1], (np.arange(1, 33) - 16) * 0.08, atol=1e-12)
    assert a.rx_offsets[15, 1] == pytest.approx(0.0, abs=1e-12)  # the (N+1)th shares the transmitter
    np.testing.assert_allclose(a.rx_length, 0.08)
    assert a.tx_length == 0.16
    w = s.waveform
    assert (w.f0, w.bandwidth, w.duration, w.fs) == (70e3, 10e3, 20e-3, 20e3)
    assert s.platform.speed == 3.0
    # Table 1 prints 2.3436 Hz; 3 / 1.28 = 2.34375 Hz is the exactly critical value (see the D/2 test).
    assert s.schedule.prf == pytest.approx(2.3436, abs=2e-4)
    assert _step(s) == pytest.approx(1.28, rel=1e-3)  # 32 x 0.04 m


# --------------------------------------------------------------------------- zhang2019


def test_zhang2019_table_1_and_documented_undersampling():
    with pytest.warns(SamplingWarning, match="undersampling"):
        s = presets.zhang2019(n_pulses=4)
    a = s.array
    assert a.n_receivers == 30
    np.testing.assert_allclose(a.rx_offsets[:, 1], 0.03 + 0.02 * np.arange(30), atol=1e-12)
    array_length = a.rx_offsets[-1, 1] + a.rx_length[-1] / 2 - (a.rx_offsets[0, 1] - a.rx_length[0] / 2)
    assert array_length == pytest.approx(0.6)  # 30 contiguous elements of 0.02 m
    np.testing.assert_allclose(a.rx_length, 0.02)
    assert a.tx_length == 0.04
    assert s.platform.speed == 2.0
    assert 1 / s.schedule.prf == pytest.approx(0.3)
    assert (s.waveform.f0, s.waveform.bandwidth) == (150e3, 20e3)
    assert _step(s) == pytest.approx(0.6)
    # 30 centres 0.01 m apart cover 0.3 m; the ping moves 0.6 m: a 0.31 m hole.
    assert phase_centre_gap(a, _step(s)) == pytest.approx(0.31)


# --------------------------------------------------------------------------- heremans2009


def test_heremans2009_section_5_2():
    s = _build("heremans2009", n_pulses=4)
    a = s.array
    assert a.n_receivers == 15
    np.testing.assert_allclose(np.diff(a.rx_offsets[:, 1]), 0.2188, atol=1e-12)
    np.testing.assert_allclose(a.rx_offsets[:, 1], (np.arange(15) - 7) * 0.2188, atol=1e-12)
    assert a.rx_offsets[7, 1] == pytest.approx(a.tx_offset[1], abs=1e-12)  # hydrophone 8 = transmitter
    assert s.platform.speed == 1.2763
    assert 1 / s.schedule.prf == pytest.approx(0.6)
    assert s.waveform.f0 == 50e3
    assert s.waveform.wavelength(s.medium) == pytest.approx(0.03)
    step = _step(s)
    assert step == pytest.approx(0.7658, abs=1e-4)
    centre_spacing = np.diff(a.rx_offsets[:, 1])[0] / 2  # phase centres sit midway to the transmitter
    assert step / centre_spacing == pytest.approx(7.0, abs=1e-3)  # 7 phase-centre spacings (eq. 50)
    # H = 15 centres, 7 new per ping: n = 8 overlap.
    assert a.n_receivers - round(step / centre_spacing) == 8


def test_preset_docstrings_state_receiver_counts():
    """The numbers checked above are the ones the docstrings cite (keeps docs and code together)."""
    assert re.search(r"32 receivers", presets.huang2022.__doc__)
    assert re.search(r"32 hydrophones", presets.wu2018.__doc__)
    assert re.search(r"30 receivers", presets.zhang2019.__doc__)
    assert re.search(r"15 hydrophones 21\.88 cm apart", presets.heremans2009.__doc__)
    assert re.search(r"sonobuoy C", presets.kiang2022.__doc__)
    assert "SamplingWarning" in presets.zhang2019.__doc__
