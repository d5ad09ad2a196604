"""Property tests (hypothesis) of the moving-target API (issue #27's defects in it among them):
nonsense refused with TypeError (a wrong kind) or ValueError (a bad value) naming the parameter,
before any large allocation; finite input in range gives finite results. Through the machinery of
tests/_properties.py (:func:`parameter_properties`)."""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings

import numpy as np
import pytest
from _properties import Domain, choices, fixed, parameter_properties, reals
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


@functools.cache
def small_scene():
    return presets.kiang2022(n_pulses=64).replace(targets=(PointTargets(CENTRE, velocity=presets.KIANG_CASES[1]),))


test_simulate_snr_reference_bad_values, test_simulate_snr_reference_valid_values, _ = parameter_properties(
    lambda **kw: clsas.simulate(small_scene(), backend="numpy", progress=False, **{"snr_db": -10.0, "seed": 1, **kw}),
    prefix="simulate", setup=small_scene, budget=None, examples=4,
    check=lambda echo: np.all(np.isfinite(echo.data)),
    domains={"snr_reference": choices(("echo", "record"))})


@functools.cache
def clean_data():
    return small_echo().data


test_snr_offset_db_bad_values, test_snr_offset_db_valid_values, _ = parameter_properties(
    lambda data=None, **kw: clsas.snr_offset_db(small_echo() if data is None else data, **kw),
    prefix="snr_offset_db", setup=small_echo, budget=None, examples=10,
    check=lambda offset: np.all(np.isfinite(offset)) and np.all(offset <= 0),
    domains={
        "data": fixed([None, clean_data()],
                      [("abc", TypeError), (3.0, TypeError), ([1.0, 2.0], TypeError),
                       (np.zeros((2, 3)), ValueError), (np.zeros((3, 0, 4), np.complex64), ValueError)]),
        "n_valid": fixed([None, [100, 100, 100]],
                         [([0, 1, 1], ValueError), ([1, 1], ValueError), ([1.5, 1, 1], TypeError),
                          ([10**9, 1, 1], ValueError), ("abc", ValueError)]),
    })


def test_snr_offset_db_refuses_a_noisy_or_compressed_echo():
    with pytest.raises(ValueError, match="snr_offset_db data: must be a noise-free echo"):
        clsas.snr_offset_db(small_echo().replace(provenance={**small_echo().provenance, "snr_db": 3.0}))
    with pytest.raises(ValueError, match="snr_offset_db data: must be a raw echo"):
        clsas.snr_offset_db(clsas.range_compress(small_echo()))


@functools.cache
def small_motion():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return clsas.estimate_motion(small_echo(), position=CENTRE)


def test_focus_moving_image_refused_by_the_budget():
    """Issue 27: half_size 1e4 m at 1 cm (2e6 x 2e6 pixels, ~29 TiB) was a MemoryError from NumPy
    under any budget; now a MemoryBudgetError naming half_size and spacing before allocating."""
    from clsas.errors import MemoryBudgetError

    with clsas.use_memory_budget(16 << 20), pytest.raises(MemoryBudgetError, match=r"half_size .* spacing"):
        clsas.focus_moving(small_echo(), small_motion(), half_size=1e4, spacing=0.01)


def pair_or_real(domain: Domain) -> Domain:
    """``domain`` for a parameter that also takes a (range, along-track) pair: a 2-list of the
    wrong kinds is no TypeError there (its values are judged), a list of another length is."""
    return Domain(domain.valid, domain.bad.filter(lambda case: not (isinstance(case[0], list) and len(case[0]) == 2)))


# every image drawn (and the default here) is millions of pixels: refused before allocating
test_focus_moving_budget_bad, _, test_focus_moving_budget = parameter_properties(
    lambda **kw: clsas.focus_moving(small_echo(), small_motion(), **{"half_size": 1e3, "spacing": 0.01, **kw}),
    prefix="focus_moving", setup=small_motion, budget=16 << 20, examples=6, may_refuse=True,
    domains={"half_size": pair_or_real(reals(0.0, 1e4, low_open=True, none=True, valid=st.floats(1e2, 1e4))),
             "spacing": reals(0.0, 100.0, low_open=True, valid=st.floats(0.01, 0.1))})


def test_delay_history_refuses_what_would_overflow_by_name():
    """delay_history(..., eta=[1e300]) returned NaN, and a scalar eta an unnamed TypeError from
    meet_time; positions, velocities and emission times are bounded as closed_forms' are
    (validate.MAX_COORDINATE, MAX_SPEED, MAX_TIME), by name, and eta of any shape works."""
    lay, p, v = layout(), (1989.0, 0.0, -350.0), (5.0, 5.0, 0.0)
    tau = moving.delay_history(lay, "A", p, v, np.array([[0.0, 1.0], [2.0, 3.0]]))
    assert tau.shape == (2, 2) and np.all(np.isfinite(tau)) and np.all(np.diff(tau.ravel()) != 0)
    assert np.ndim(moving.delay_history(lay, "A", p, v, 0.5)) == 0
    for eta in ([1e300], [np.nan], 1e7):
        with pytest.raises(ValueError, match="^delay_history eta: must"):
            moving.delay_history(lay, "A", p, v, eta)
    for eta in ("a", None, [1j]):
        with pytest.raises(TypeError, match="^delay_history eta: must"):
            moving.delay_history(lay, "A", p, v, eta)
    with pytest.raises(ValueError, match="^delay_history position: must be within"):
        moving.delay_history(lay, "A", (1e300, 0.0, 0.0), v, [0.0])
    with pytest.raises(ValueError, match="^delay_history velocity: must be within"):
        moving.delay_history(lay, "A", p, (1500.0, 0.0, 0.0), [0.0])


def test_focus_moving_half_size_of_another_length_is_a_type_error():
    """half_size takes a number or a (range, along-track) pair: [0, 0, 0] was a ValueError while
    the property suite's wrong kinds (lists for a real) are TypeErrors (it failed when hypothesis
    drew one); a pair with a zero is a ValueError on its value."""
    with pytest.raises(TypeError, match=r"focus_moving half_size: must be a number or \(range, along-track\)"):
        clsas.focus_moving(small_echo(), small_motion(), half_size=[0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"focus_moving half_size: must be in \(0, 10000\] m, got 0"):
        clsas.focus_moving(small_echo(), small_motion(), half_size=[0.0, 0.0])
