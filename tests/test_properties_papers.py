"""Property tests (hypothesis) for the papers' imagers: numerical PTRS imaging (Zhang et al.
2019, :func:`clsas.ptrs_image`) and the inclined-array correction (Wu et al. 2018,
:func:`clsas.correct_inclined_array`). Invalid values drawn per parameter raise the documented
error (TypeError for a wrong kind, ValueError for a bad value) naming the parameter, on both
backends alike, and nothing finite comes back as inf or NaN."""

from __future__ import annotations

import functools
import warnings

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from test_properties_validation import CHECKS, bad_integers, bad_reals, not_none, raises

import clsas
from clsas.image.inclined import correct_inclined_array
from clsas.image.ptrs import ptrs_image
from clsas.scene import presets
from clsas.scene.targets import PointTargets

FLAGS = st.tuples(st.one_of(st.sampled_from(["no", "yes", "", 0, 1, None, 1.0]), st.lists(st.booleans(), max_size=2)),
                  st.just(TypeError))


@functools.cache
def zhang_echo():
    """Zhang et al.'s sonar (30 receivers, PRI 0.15 s), 8 pulses, one point at 44 m."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sc = presets.zhang2019(n_pulses=8, receivers=30, pri=0.15).replace(targets=(PointTargets([[44.0, 0.0, 0.0]]),))
        return clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False))


@functools.cache
def wu_echo():
    """Wu et al.'s inclined array, 8 pulses, the five points."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return clsas.range_compress(clsas.simulate(presets.wu2018_inclined(n_pulses=8), backend="opencl",
                                                   progress=False))


@CHECKS
@given(st.one_of(
    st.tuples(st.just("block_width"), not_none(bad_reals(0.0, 1e6, low_open=True))),
    st.tuples(st.just("reference_ranges"), not_none(bad_reals(40.0, 48.0, low_open=True, high_open=True))),
    st.tuples(st.just("depth"), not_none(bad_reals(-1e6, 1e6))),
    st.tuples(st.just("workers"), not_none(bad_integers(-1024, 1024))),
    st.tuples(st.just("deconvolve"), FLAGS),
    st.tuples(st.just("rcmc"), FLAGS),
    st.tuples(st.just("window"), st.tuples(st.sampled_from(["box", "", "HAMMING", 3, None]), st.just(ValueError))),
    st.tuples(st.sampled_from(["interp", "tap_window"]),
              st.tuples(st.sampled_from(["cubic", "", "SINC8", "hann", 8, None]), st.just(ValueError))),
))
def test_ptrs_image_arguments(opencl_device, case):
    name, (value, error) = case
    if name == "reference_ranges" and isinstance(value, list):
        value, error = [*value, 1e9], ValueError  # a list of floats is the right kind; 1e9 m is out of the record
    messages = {str(raises(error, f"ptrs_image {name}",
                           lambda backend=backend: ptrs_image(zhang_echo(), backend=backend, **{name: value})))
                for backend in ("numpy", "opencl")}
    assert len(messages) == 1, messages


@CHECKS
@given(st.one_of(
    st.tuples(st.just("r_ref"), not_none(bad_reals(0.0, 1e6, low_open=True))),
    st.tuples(st.just("depth"), not_none(bad_reals(-1e6, 1e6))),
    st.tuples(st.just("workers"), not_none(bad_integers(-1024, 1024))),
    st.tuples(st.just("stop_and_go"), FLAGS.filter(lambda case: case[0] is not None)),
    st.tuples(st.just("correct"), st.tuples(st.sampled_from(["roll", ("yaw", "roll"), (1,), [None]]),
                                            st.just(ValueError))),
))
def test_correct_inclined_array_arguments(opencl_device, case):
    name, (value, error) = case
    raises(error, f"correct_inclined_array {name}", lambda: correct_inclined_array(wu_echo(), **{name: value}))


@CHECKS
@given(scale=st.floats(min_value=1e30, max_value=3.3e38))
def test_loud_records_are_refused_not_returned_as_inf(opencl_device, scale):
    """Samples scaled up to ``scale``: either a finite result or a ValueError naming echo.data."""
    for call, echo in ((ptrs_image, zhang_echo()), (correct_inclined_array, wu_echo())):
        loud = echo.replace(data=(echo.data.astype(np.complex128) * (scale / np.abs(echo.data).max())).astype(np.complex64))
        try:
            out = call(loud)
        except ValueError as err:
            assert "echo.data" in str(err) or "overflows" in str(err), err
        else:
            assert np.all(np.isfinite(out.data))


def test_wrong_kinds_of_echo(opencl_device):
    for value in (None, "echo", np.zeros(4)):
        raises(TypeError, "echo", lambda: ptrs_image(value))
        raises(TypeError, "correct_inclined_array echo", lambda: correct_inclined_array(value))
