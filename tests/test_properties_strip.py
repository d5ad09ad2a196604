"""Property tests (hypothesis) of the strip-map imagers' template (clsas.image.strip), the record
conversions and the Stolt map: invalid values drawn per parameter raise the documented error
(TypeError for the wrong kind, ValueError for a bad value, naming the parameter), the same on
both backends (the machinery of tests/test_properties_validation.py)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from test_properties_validation import (
    CHECKS,
    WRONG_KIND,
    _same_on_both_backends,
    bad_integers,
    bad_reals,
    not_none,
    raises,
    small,
)

import clsas
from clsas.image.record import line_record
from clsas.image.stolt import StoltAxes, stolt

IMAGERS = st.sampled_from(["omega_k", "range_doppler", "chirp_scaling", "nonlinear_chirp_scaling"])
STOLT_AXES = dict(f_first=-5e3, df=100.0, n_src=100, kx_first=-40.0, dkx=0.8, n_out=100, f0=50e3, c=1500.0)


@CHECKS
@given(imager=IMAGERS, case=st.one_of(
    st.tuples(st.just("depth"), not_none(bad_reals(-1e6, 1e6))),
    st.tuples(st.just("workers"), bad_integers(-1024, 1024).filter(lambda c: c[0] is not None)),
    st.tuples(st.just("workers"), st.just((0, ValueError))),
    st.tuples(st.just("deconvolve"), st.tuples(st.sampled_from(["no", None, 1, 0.0, "True"]), st.just(TypeError))),
    st.tuples(st.just("interp"), st.tuples(st.sampled_from(["cubic", "", "SINC8", None, 8]), st.just(ValueError))),
    st.tuples(st.just("tap_window"), st.tuples(st.sampled_from(["hann", None, 5]), st.just(ValueError))),
    st.tuples(st.just("window"), st.tuples(st.sampled_from(["blackman", None, 3]), st.just(ValueError))),
    st.tuples(st.just("elements"), st.tuples(st.sampled_from([np.nan, -0.1, 0.0, 1e300, [0.1, np.inf], [0.1, 0.1, 0.1]]),
                                             st.just(ValueError))),
    st.tuples(st.just("elements"), st.tuples(st.sampled_from(["a", [None, 0.1], object()]), st.just(TypeError))),
    st.tuples(st.just("kaiser_beta"), bad_reals(0.0, 100.0)),
))
def test_strip_imager_options(opencl_device, imager, case):
    name, (value, error) = case
    _, echo = small()
    _same_on_both_backends(f"{imager} {name}", error,
                           lambda backend: getattr(clsas, imager)(echo, backend=backend, **{name: value}))


@CHECKS
@given(imager=IMAGERS, value=st.sampled_from([np.nan, np.inf, -np.inf, 1e300, 3e38]))
def test_strip_imagers_refuse_samples_that_are_not_finite_or_overflow(opencl_device, imager, value):
    """A LineRecord holding NaN, inf or samples that overflow complex64 through the transforms."""
    _, echo = small()
    rec = line_record(echo, backend="numpy")
    data = rec.data.astype(np.complex128)
    data[2, 5] = value
    _same_on_both_backends(f"{imager} data", ValueError,
                           lambda backend: getattr(clsas, imager)(rec.replace(data=data), backend=backend))


@CHECKS
@given(case=st.one_of(
    st.tuples(st.sampled_from(["u0", "t0"]), bad_reals(-1e6, 1e6)),
    st.tuples(st.sampled_from(["du", "fs"]), bad_reals(0.0, 1e6, low_open=True)),
    st.tuples(st.just("speed"), bad_reals(0.0, 100.0)),
    st.tuples(st.just("nonstop"), st.tuples(st.sampled_from(["no", 1, None]), st.just(TypeError))),
    st.tuples(st.just("track"), st.tuples(st.sampled_from([[0.0], [np.nan, 0.0], [1e300, 0.0]]), st.just(ValueError))),
    st.tuples(st.just("waveform"), st.tuples(WRONG_KIND, st.just(TypeError))),
))
def test_line_record_fields(case):
    name, (value, error) = case
    if name == "fs" and error is ValueError and isinstance(value, float) and 1e6 < value <= 1e11:
        return  # fs is allowed up to clsas.model.MAX_ECHO_FS
    _, echo = small()
    rec = line_record(echo, backend="numpy")
    raises(error, f"LineRecord.{name}", lambda: rec.replace(**{name: value}))


@CHECKS
@given(case=st.one_of(
    st.tuples(st.sampled_from(["c", "df", "dkx", "f0"]), bad_reals(0.0, 1e12, low_open=True)),
    st.tuples(st.sampled_from(["f_first", "kx_first"]), bad_reals(-1e12, 1e12)),
    st.tuples(st.sampled_from(["n_src", "n_out"]), bad_integers(1, 2**31 - 1)),
))
def test_stolt_axes(case):
    name, (value, error) = case
    raises(error, f"StoltAxes.{name}", lambda: StoltAxes(**{**STOLT_AXES, name: value}))


@CHECKS
@given(rows=st.integers(0, 0) | st.just(1), ku=st.sampled_from([np.nan, np.inf, 1e300]))
def test_stolt_arrays(opencl_device, rows, ku):
    """No rows, or a wavenumber that is not finite: a ValueError on both backends."""
    axes = StoltAxes(**STOLT_AXES)
    spectrum = np.ones((rows, 100), np.complex64)
    wavenumbers = np.full(rows, ku)
    _same_on_both_backends("stolt", ValueError, lambda backend: stolt(spectrum, wavenumbers, axes, backend=backend))


@CHECKS
@given(case=st.one_of(
    st.tuples(st.just("stop_and_go"), st.tuples(st.sampled_from(["no", 1, 0.5]), st.just(TypeError))),
    st.tuples(st.just("compensate"), st.tuples(st.sampled_from(["no", 1, None]), st.just(TypeError))),
    st.tuples(st.just("reference_range"), not_none(bad_reals(0.0, 1.0, low_open=True))),
))
def test_pca_record_options(opencl_device, case):
    name, (value, error) = case
    if name == "reference_range" and error is ValueError and isinstance(value, float) and 0.0 < value <= 1e3:
        return  # a range the record reaches is allowed
    _, echo = small()
    _same_on_both_backends(name, error, lambda backend: clsas.pca_record(echo, backend=backend, **{name: value}))
