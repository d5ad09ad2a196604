"""Property tests (hypothesis) of fast factorised back-projection's and prepare's arguments: a value
of the wrong kind raises TypeError, a value out of range ValueError, each naming the parameter,
the same on both backends (the machinery of tests/test_properties_validation.py)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from test_properties_validation import (CHECKS, _same_on_both_backends, bad_integers, bad_reals, not_none, raises,
                                        small)

import clsas
from clsas import Grid
from clsas.image.backprojection import prepare

GRID = Grid.plane(np.linspace(29, 31, 4), np.linspace(-1, 1, 4), 0.0)


@CHECKS
@given(st.one_of(
    st.tuples(st.just("aperture"), not_none(bad_reals(0.0, np.pi, low_open=True))),
    st.tuples(st.just("factor"), bad_integers(2, 16)),
    st.tuples(st.just("tolerance"), bad_reals(0.0, 1.0, low_open=True, high_open=True)),
    st.tuples(st.just("first"), not_none(bad_integers(1, 8))),
    st.tuples(st.just("taps"), st.tuples(st.sampled_from([0, 2, 6, 16, True, "8", 8.0]), st.just(ValueError))),
    st.tuples(st.just("stop_and_go"), st.tuples(st.one_of(st.text(max_size=3), st.none(), st.integers()),
                                                 st.just(TypeError))),
))
def test_ffbp_arguments(opencl_device, case):
    name, (value, error) = case
    _, echo = small()
    _same_on_both_backends(f"ffbp {name}", error,
                           lambda backend: clsas.ffbp(echo, GRID, backend=backend, progress=False, **{name: value}))


@CHECKS
@given(st.one_of(
    st.tuples(st.just("upsample"), bad_integers(1, 64)),
    st.tuples(st.just("interp"), st.tuples(st.sampled_from(["cubic", "", "LINEAR", 3]), st.just(ValueError))),
    st.tuples(st.just("grid"), st.tuples(st.one_of(st.text(max_size=5), st.booleans(), st.just(object()),
                                                   st.just((1.0, 2.0, 3.0))), st.just(TypeError))),
    st.tuples(st.just("grid"), st.tuples(st.sampled_from([(2.0, 1.0), (0.0, 0.0), (np.nan, 1.0), (0.0, np.inf)]),
                                         st.just(ValueError))),
))
def test_prepare_arguments(case):
    name, (value, error) = case
    _, echo = small()
    raises(error, name, lambda: prepare(echo, **{name: value}))


@CHECKS
@given(upsample=st.integers(2, 64), fraction=st.floats(0.01, 0.9))
def test_prepare_refuses_over_the_budget_before_upsampling(upsample, fraction):
    """A budget below what the upsampled records hold (8 bytes a sample, upsample samples an
    original one) is refused, naming the upsampling, before any FFT."""
    _, echo = small()
    need = 8 * upsample * echo.n_samples * echo.n_pulses
    with clsas.use_memory_budget(max(1, int(fraction * need))):
        raises(clsas.budget.MemoryBudgetError, f"upsample={upsample}", lambda: prepare(echo, upsample=upsample))
