"""Property tests (hypothesis) of the moving-target API (issue #27's defects in it among them):
nonsense refused with TypeError (a wrong kind) or ValueError (a bad value) naming the parameter,
before any large allocation; finite input in range gives finite results. Through the machinery of
tests/_properties.py (:func:`parameter_properties`)."""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from _properties import fixed, parameter_properties, reals
from hypothesis import strategies as st

import clsas
from clsas import PointTargets
from clsas.estimate import moving
from clsas.scene import presets

CENTRE = (1989.0, 0.0, -350.0)
VECTOR_BAD = [((math.nan, 0.0, 0.0), ValueError), ((1e300, 0.0, 0.0), ValueError), ((math.inf, 0.0, 0.0), ValueError),
              ((1.0, 2.0), ValueError), ("abc", TypeError), (None, TypeError), (True, TypeError), (1j, TypeError),
              (object(), TypeError), ((1j, 0.0, 0.0), TypeError), (("a", 0.0, 0.0), TypeError)]


@functools.cache
def layout():
    return moving.layout_of(presets.kiang2022(n_pulses=64))


@functools.cache
def small_echo():
    """64 pulses of case 1's point target (the fewest the chain takes)."""
    scene = presets.kiang2022(n_pulses=64).replace(targets=(PointTargets(CENTRE, velocity=presets.KIANG_CASES[1]),))
    return clsas.simulate(scene, backend="numpy", progress=False)


def _finite(result):
    for name, predicted in result.items():
        values = [getattr(predicted, f.name) for f in dataclasses.fields(predicted)]
        assert np.all(np.isfinite(values)), (name, predicted)


def vectors(low, high):
    return st.tuples(*(st.floats(low, high) for _ in range(3)))


test_closed_forms_bad_values, test_closed_forms_valid_values, _ = parameter_properties(
    lambda position=CENTRE, velocity=(0.0, -4.0, 0.0), **kw: moving.closed_forms(layout(), position, velocity, **kw),
    prefix="closed_forms", setup=layout, check=_finite, budget=None, examples=20,
    domains={
        # the target away from the sonar (x >= 100 m: a point on a receiver has no direction)
        "position": fixed([CENTRE, (100.0, -50.0, -10.0), (9e5, 3e5, -2e3)], VECTOR_BAD
                          + [((-2e6, 0.0, 0.0), ValueError)]),
        "velocity": fixed([(0.0, 0.0, 0.0), (99.0, -99.0, 99.0), (0.0, -4.0, 0.0)],
                          VECTOR_BAD + [((1500.0, 0.0, 0.0), ValueError), ((0.0, 101.0, 0.0), ValueError)]),
        "eta_ref": reals(-1e6, 1e6, none=True, valid=st.floats(-100.0, 100.0)),
        "model": fixed(["exact", "paper"], [("", ValueError), ("unknown", ValueError)]),
    })


test_solve_velocity_bad_values, test_solve_velocity_valid_values, test_solve_velocity_budget = parameter_properties(
    lambda fm_rates=None, **kw: moving.solve_velocity(layout(), CENTRE, {"A": 6.5, "B": -79.8, "C": 2.7},
                                                      fm_rates=fm_rates, **kw),
    prefix="solve_velocity", setup=layout, budget=4 << 20, examples=10, may_refuse=True,
    check=lambda sol: np.all(np.isfinite(sol.velocity)),
    domains={
        "v_max": reals(0.0, 100.0, low_open=True, valid=st.floats(8.0, 24.0)),
        "step": reals(0.0, 100.0, low_open=True, valid=st.floats(2.0, 8.0)),
        "fm_rates": fixed([None, {"A": 4.87, "B": 4.82, "C": 3.08}],
                          [({"A": math.nan}, ValueError, "fm_rates['A']"), ({"A": math.inf}, ValueError, "fm_rates['A']"),
                           ({"A": "x"}, TypeError, "fm_rates['A']"), ({"Z": 1.0}, ValueError, "'Z'")]),
    })


@pytest.mark.parametrize("value, error", [v for v in VECTOR_BAD if v[0] is not None])
def test_estimate_motion_position_refused_by_kind(value, error):
    with pytest.raises(error, match="position"):
        clsas.estimate_motion(small_echo(), position=value)


@pytest.mark.parametrize("eta", ["zeros", "reversed", "repeated"])
def test_estimate_motion_refuses_pulse_times_that_do_not_increase(eta):
    echo = small_echo()
    times = {"zeros": np.zeros_like(echo.eta), "reversed": echo.eta[::-1].copy(),
             "repeated": np.repeat(echo.eta[::2], 2)}[eta]
    with pytest.raises(ValueError, match=r"echo\.eta must increase"):
        clsas.estimate_motion(echo.replace(eta=times), position=CENTRE)


def test_closed_forms_eta_ref_moves_a_layout():
    """A Layout given with eta_ref is referred to it (not ignored): the same as the scenario's."""
    scene = presets.kiang2022(n_pulses=64)
    from_layout = moving.closed_forms(moving.layout_of(scene), CENTRE, (0.0, -4.0, 0.0), eta_ref=5.0)
    from_scene = moving.closed_forms(scene, CENTRE, (0.0, -4.0, 0.0), eta_ref=5.0)
    for name in from_scene:
        assert from_layout[name].fm_rate == pytest.approx(from_scene[name].fm_rate, rel=1e-9)
        assert from_layout[name].doppler_centroid == pytest.approx(from_scene[name].doppler_centroid, rel=1e-9)
        assert from_layout[name].tau_c == pytest.approx(from_scene[name].tau_c, rel=1e-12)
