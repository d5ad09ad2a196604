"""Property tests (hypothesis) of DPCA's public functions: nonsense refused with TypeError or
ValueError naming the parameter (issue #27's cases among them), before any large allocation;
finite input gives finite tracks."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from test_properties_validation import CHECKS, bad_reals, raises

from clsas import EchoData, Medium
from clsas.errors import MemoryBudgetError
from clsas.estimate import dpca
from clsas.scene import presets


@functools.cache
def small():
    """Heremans' array, 6 pings of 512 samples of noise shared between coinciding phase centres
    (no simulation): (echo, array, speed), and its ping pairs."""
    scene = presets.heremans2009(n_pulses=6)
    shift, _ = dpca.nominal_shift(scene.array, scene.platform.speed, scene.schedule.prf)
    h, n = scene.array.n_receivers, 512
    rng = np.random.default_rng(0)
    centres = rng.standard_normal((shift * 6 + h, n)) + 1j * rng.standard_normal((shift * 6 + h, n))
    data = centres[shift * np.arange(6)[None, :] + np.arange(h)[:, None]].astype(np.complex64)
    echo = EchoData(data=data, eta=scene.eta, t0=np.full(h, 0.12), fs=scene.waveform.fs, tx_pos=np.zeros((6, 3)),
                    rx_pos=np.zeros((h, 6, 1, 3)), rx_tau=np.zeros((h, 1)), waveform=scene.waveform, medium=Medium(),
                    receivers=scene.receiver_names, compressed=True)
    pairs = dpca.estimate(echo, scene.array, scene.platform.speed)
    return echo, scene.array, scene.platform.speed, pairs


def test_estimate_checks_the_budget_first():
    echo, array, speed, _ = small()
    raises(MemoryBudgetError, "dpca.estimate", lambda: dpca.estimate(echo, array, speed, n_angles=10**7))


@CHECKS
@given(st.sampled_from(["speed", "min_coherence", "lags", "t_lags", "block", "n_angles", "extent"]), st.data())
def test_estimate_refuses_nonsense_by_name(name, data):
    echo, array, speed, _ = small()
    if name in ("speed",):
        value, error = data.draw(bad_reals(0.0, None, low_open=True))
    elif name == "min_coherence":
        value, error = data.draw(bad_reals(0.0, 1.0, high_open=True))
    elif name == "extent":
        value, error = data.draw(st.sampled_from([("x", ValueError), ("beam", ValueError), ((0, 1), TypeError),
                                                  (1.0, TypeError)]))
    else:
        value, error = data.draw(st.one_of(st.tuples(st.integers(max_value=0), st.just(ValueError)),
                                           st.tuples(st.sampled_from([2.0, "3", None, True]), st.just(TypeError))))
    kwargs = {"speed": speed}
    kwargs[name] = value
    raises(error, f"dpca.estimate {name}", lambda: dpca.estimate(echo, array, **kwargs))


@CHECKS
@given(st.sampled_from(["speed", "heading0"]), st.data())
def test_integrate_refuses_nonsense_by_name(name, data):
    echo, array, speed, pairs = small()
    value, error = data.draw(bad_reals(0.0, None, low_open=True) if name == "speed" else bad_reals(-0.5, 0.5))
    args = {"speed": speed, "heading0": 0.0, name: value}
    raises(error, f"dpca.integrate {name}", lambda: dpca.integrate(pairs, echo.eta, args["speed"], array,
                                                                   heading0=args["heading0"]))


def test_integrate_issue27_cases():
    echo, array, speed, pairs = small()
    raises(ValueError, "overlapping phase centres", lambda: dpca.integrate(pairs, echo.eta, 1e300, array))
    raises(ValueError, "dpca.integrate speed", lambda: dpca.integrate(pairs, echo.eta, np.inf, array))
    raises(ValueError, "dpca.integrate speed", lambda: dpca.integrate(pairs, echo.eta, 0.0, array))
    raises(ValueError, "dpca.integrate eta", lambda: dpca.integrate(pairs, np.zeros(echo.n_pulses), speed, array))
    raises(ValueError, "dpca.integrate eta", lambda: dpca.integrate(pairs, echo.eta[:-1], speed, array))
    raises(ValueError, "dpca.integrate eta", lambda: dpca.integrate(pairs, echo.eta * np.nan, speed, array))
    raises(TypeError, "dpca.integrate pairs", lambda: dpca.integrate(None, echo.eta, speed, array))
    raises(TypeError, "dpca.integrate array", lambda: dpca.integrate(pairs, echo.eta, speed, ""))
    track = dpca.integrate(pairs, echo.eta, speed, array)
    for values in (track.cross, track.heading, track.along, track.cross_std, track.heading_std):
        assert np.all(np.isfinite(values))


@CHECKS
@given(st.sampled_from(["speed", "prf"]), bad_reals(0.0, None, low_open=True))
def test_nominal_shift_refuses_nonsense(name, case):
    value, error = case
    array = presets.heremans2009(n_pulses=2).array
    args = {"speed": 1.2763, "prf": 1 / 0.6, name: value}
    raises(error, f"nominal_shift {name}", lambda: dpca.nominal_shift(array, args["speed"], args["prf"]))


@CHECKS
@given(st.sampled_from(["f0", "c"]), bad_reals(0.0, None, low_open=True))
def test_beam_sin2_refuses_nonsense(name, case):
    value, error = case
    array = presets.heremans2009(n_pulses=2).array
    args = {"f0": 50e3, "c": 1500.0, name: value}
    raises(error, f"beam_sin2 {name}", lambda: dpca.beam_sin2(array, args["f0"], args["c"]))


def test_small_functions_issue27_cases():
    array = presets.heremans2009(n_pulses=2).array
    raises(ValueError, "nominal_shift prf", lambda: dpca.nominal_shift(array, 1.2763, 0.0))
    raises(ValueError, "beam_sin2 f0", lambda: dpca.beam_sin2(array, 0.0, 1500.0))
    raises(TypeError, "nominal_shift: array", lambda: dpca.nominal_shift("", 1.0, 1.0))
    raises(ValueError, "delay_records data", lambda: dpca.delay_records(np.zeros((2, 3, 0), np.complex64),
                                                                        np.zeros((2, 3)), 5e4, 1e4))
    raises(ValueError, "delay_records data", lambda: dpca.delay_records(np.zeros((2, 3)), np.zeros((2, 3)), 5e4, 1e4))


@CHECKS
@given(st.floats(-1e3, 1e3), st.floats(0.1, 1e3), st.floats(-50, 50), st.floats(0.1, 100))
def test_look_moments_are_moments(x0, width, y0, length):
    """Any rectangle: <sin^2> in [0, 1], the main-lobe fraction in [0, 1], content >= 0 and 0
    exactly where <sin^2> is NaN."""
    array = presets.heremans2009(n_pulses=2).array
    extent = dpca.SeafloorExtent(x=(x0, x0 + width) if x0 + width > 0 else (0.0, 1.0), y=(y0, y0 + length))
    sin2, fraction, content = dpca.look_moments(array, 50e3, 1500.0, np.array([5.0, 50.0, 500.0]),
                                                np.zeros((2, 3)), extent, span=1.0)
    assert np.all((content >= 0) & (fraction >= 0) & (fraction <= 1 + 1e-12))
    assert np.array_equal(np.isnan(sin2), content == 0)
    assert np.all(sin2[~np.isnan(sin2)] >= 0) and np.all(sin2[~np.isnan(sin2)] <= 1)
