"""Property tests (hypothesis): invalid values drawn per parameter raise the documented error.

The machinery (bad_reals, bad_integers, raises, ...) lives in tests/_properties.py. The rule
(clsas.validate): a value of the wrong kind (a string, None, a bool, a list where a
number belongs; a float where an integer belongs) raises TypeError; a value of the right kind
outside what is allowed (NaN, inf, out of range, too large to be a float) raises ValueError; a
request over the memory budget raises MemoryBudgetError (a ValueError). Every message names the
parameter. Entry points with two backends raise the same error on both.
"""

from __future__ import annotations

import functools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import clsas
from clsas import Grid, Medium, Platform, PulseSchedule, Recording, Waveform
from clsas.scene.scenario import Array, Scenario
from clsas.scene.targets import PointTargets

# the machinery, kept importable from here for the property files that import it from this one
from _properties import (  # noqa: E402,F401
    CHECKS,
    WRONG_KIND,
    bad_integers,
    bad_reals,
    not_none,
    raises,
    same_on_both_backends,
)

_same_on_both_backends = same_on_both_backends


WAVE = dict(f0=50e3, bandwidth=10e3, duration=2e-3, fs=20e3)


@CHECKS
@given(st.one_of(
    st.tuples(st.just("Medium.sound_speed"), bad_reals(1000.0, 2000.0)),
    st.tuples(st.just("Waveform.f0"), bad_reals(0.0, 1e8, low_open=True)),
    st.tuples(st.just("Waveform.bandwidth"), bad_reals(0.0, 100e3, low_open=True, high_open=True)),
    st.tuples(st.just("Waveform.duration"), bad_reals(0.0, 10.0, low_open=True)),
    st.tuples(st.just("Waveform.fs"), bad_reals(10e3, 1e9)),
    st.tuples(st.just("Platform.speed"), bad_reals(0.0, 100.0, low_open=True)),
    st.tuples(st.just("PulseSchedule.prf"), bad_reals(0.0, 1e5, low_open=True)),
    st.tuples(st.just("PulseSchedule.n_pulses"), bad_integers(1)),
    st.tuples(st.just("Array.uniform_line spacing"), bad_reals(0.0, 1e6, low_open=True)),
    st.tuples(st.just("Array.uniform_line n_receivers"), bad_integers(1)),
    st.tuples(st.just("Array.tx_length"), bad_reals(0.0, 100.0)),
))
def test_scene_fields(case):
    name, (value, error) = case
    build = {
        "Medium.sound_speed": lambda x: Medium(x),
        "Waveform.f0": lambda x: Waveform(**{**WAVE, "f0": x}),
        "Waveform.bandwidth": lambda x: Waveform(**{**WAVE, "bandwidth": x}),
        "Waveform.duration": lambda x: Waveform(**{**WAVE, "duration": x}),
        "Waveform.fs": lambda x: Waveform(**{**WAVE, "fs": x}),
        "Platform.speed": lambda x: Platform(speed=x),
        "PulseSchedule.prf": lambda x: PulseSchedule(prf=x, n_pulses=4),
        "PulseSchedule.n_pulses": lambda x: PulseSchedule(prf=10.0, n_pulses=x),
        "Array.uniform_line spacing": lambda x: Array.uniform_line(4, x, 0.0),
        "Array.uniform_line n_receivers": lambda x: Array.uniform_line(x, 0.1, 0.0),
        "Array.tx_length": lambda x: Array(rx_offsets=[[0.0, 0.0, 0.0]], tx_length=x),
    }[name]
    raises(error, name, lambda: build(value))


@CHECKS
@given(st.one_of(
    st.tuples(st.just("PointTargets.positions"), st.sampled_from([[[1e7, 0, 0]], [[np.nan, 0, 0]], [[0, 0]], []]),
              st.just(ValueError)),
    st.tuples(st.just("PointTargets.positions"), st.sampled_from(["abc", [["a", 0, 0]], None]), st.just(TypeError)),
    st.tuples(st.just("PointTargets.velocity"),
              st.floats(100.01, 1e6).map(lambda s: [0.0, s, 0.0]) | st.just([np.inf, 0, 0]), st.just(ValueError)),
    st.tuples(st.just("PointTargets.reflectivity"), st.sampled_from([np.nan, 1e16, complex(0, np.inf)]),
              st.just(ValueError)),
    st.tuples(st.just("Platform.start"), st.floats(1e6, 1e300, exclude_min=True).map(lambda x: [x, 0.0, 0.0]),
              st.just(ValueError)),
    st.tuples(st.just("Recording.n_samples"), st.integers(max_value=0), st.just(ValueError)),
    st.tuples(st.just("Recording.t0"), st.sampled_from([np.nan, 1e7, -np.inf]), st.just(ValueError)),
))
def test_scene_arrays(case):
    name, value, error = case
    build = {
        "PointTargets.positions": lambda x: PointTargets(x),
        "PointTargets.velocity": lambda x: PointTargets([[1.0, 0, 0]], velocity=x),
        "PointTargets.reflectivity": lambda x: PointTargets([[1.0, 0, 0]], reflectivity=x),
        "Platform.start": lambda x: Platform(speed=1.0, start=x),
        "Recording.n_samples": lambda x: Recording(t0=0.0, n_samples=x),
        "Recording.t0": lambda x: Recording(t0=x, n_samples=10),
    }[name]
    raises(error, name, lambda: build(value))


@functools.cache
def small():
    """A one-receiver scene (target 30 m away, 8 pulses) and its compressed echo."""
    return SMALL_SCENE, clsas.range_compress(small_raw())


@functools.cache
def small_raw():
    return clsas.simulate(SMALL_SCENE, backend="numpy", progress=False)


SMALL_SCENE = Scenario(medium=Medium(), waveform=Waveform(**WAVE), platform=Platform(speed=0.5),
                       array=Array(rx_offsets=[[0.0, 0.0, 0.0]]), schedule=PulseSchedule(prf=10.0, n_pulses=8),
                       targets=(PointTargets([[30.0, 0.0, 0.0]]),))


@CHECKS
@given(st.one_of(
    st.tuples(st.just("snr_db"), not_none(bad_reals(-100.0, 200.0))),
    st.tuples(st.just("seed"), not_none(bad_integers(0))),
    st.tuples(st.just("reuse_tolerance"), bad_reals(0.0, np.pi)),
    st.tuples(st.just("spreading"), st.tuples(st.sampled_from([0, 1, "yes", None]), st.just(TypeError))),
))
def test_simulate_arguments(opencl_device, case):
    name, (value, error) = case
    sc = SMALL_SCENE
    kwargs = {name: value, **({"seed": 1} if name == "snr_db" else {"snr_db": 10.0} if name == "seed" else {})}
    _same_on_both_backends(f"simulate {name}", error,
                           lambda backend: clsas.simulate(sc, backend=backend, progress=False, **kwargs))


def test_simulate_refuses_too_many_pulses_before_any_delay(opencl_device):
    big = SMALL_SCENE.replace(schedule=PulseSchedule(prf=1e4, n_pulses=10**8))
    with clsas.use_memory_budget("1G"):
        _same_on_both_backends("max_bytes", clsas.errors.MemoryBudgetError,
                               lambda backend: clsas.simulate(big, backend=backend, progress=False))


@CHECKS
@given(st.one_of(
    st.tuples(st.just("upsample"), bad_integers(1, 64)),
    st.tuples(st.just("kaiser_beta"), bad_reals(0.0, 100.0)),
    st.tuples(st.just("taylor_nbar"), bad_integers(1, 100)),
    st.tuples(st.just("taylor_sll_db"), bad_reals(0.0, 200.0, low_open=True)),
    st.tuples(st.just("workers"), not_none(bad_integers(-1024, 1024))),
))
def test_range_compress_arguments(case):
    name, (value, error) = case
    raw = small_raw()
    window = {"kaiser_beta": "kaiser", "taylor_nbar": "taylor", "taylor_sll_db": "taylor"}.get(name, "none")
    raises(error, name, lambda: clsas.range_compress(raw, window=window, **{name: value}))


@CHECKS
@given(st.one_of(
    st.tuples(st.just("upsample"), bad_integers(1, 64)),
    st.tuples(st.just("aperture"), not_none(bad_reals(0.0, np.pi, low_open=True))),
    st.tuples(st.just("interp"), st.tuples(st.sampled_from(["cubic", "", "LINEAR", 3]), st.just(ValueError))),
    st.tuples(st.just("target_velocity"),
              st.tuples(st.sampled_from([[0, 200.0, 0], [np.nan, 0, 0], [1e300, 0, 0], [1, 2]]), st.just(ValueError))),
))
def test_backproject_arguments(opencl_device, case):
    name, (value, error) = case
    _, echo = small()
    grid = Grid.plane(np.linspace(29, 31, 4), np.linspace(-1, 1, 4), 0.0)
    _same_on_both_backends(f"backproject {name}", error,
                           lambda backend: clsas.backproject(echo, grid, backend=backend, progress=False,
                                                             **{name: value}))


@CHECKS
@given(n=st.integers(0, 7), backend=st.sampled_from(["numpy", "opencl"]))
def test_backproject_refuses_records_too_short(opencl_device, n, backend):
    _, echo = small()
    short = echo.replace(data=echo.data[:, :, :n].copy())
    grid = Grid.plane([30.0], [0.0], 0.0)
    raises(ValueError, "backproject echo", lambda: clsas.backproject(short, grid, interp="sinc8", backend=backend,
                                                                     progress=False))


@settings(max_examples=10, deadline=None, derandomize=True)
@given(imager=st.sampled_from(["omega_k", "range_doppler", "chirp_scaling"]), n=st.integers(1, 15),
       backend=st.sampled_from(["numpy", "opencl"]))
def test_imagers_refuse_records_too_short(opencl_device, imager, n, backend):
    _, echo = small()
    short = echo.replace(data=echo.data[:, :, :n].copy())
    raises(ValueError, f"{imager} data", lambda: getattr(clsas, imager)(short, backend=backend))


@CHECKS
@given(st.one_of(
    st.tuples(st.just("Grid.plane z"), bad_reals(-1e6, 1e6)),
    st.tuples(st.just("Grid.plane x"), st.tuples(st.sampled_from([[np.nan], [1e7], [-np.inf, 0]]), st.just(ValueError))),
    st.tuples(st.just("Grid.plane x"), st.tuples(st.sampled_from(["abc", [None], [[1, "a"]]]), st.just(TypeError))),
))
def test_grid_arguments(case):
    name, (value, error) = case
    if name == "Grid.plane z":
        raises(error, name, lambda: Grid.plane([0.0], [0.0], value))
    else:
        raises(error, name, lambda: Grid.plane(value, [0.0], 0.0))
