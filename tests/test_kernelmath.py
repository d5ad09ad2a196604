"""kernels/common.h helpers (through kernels/kernelmath.cl) against their NumPy twins."""

from __future__ import annotations

import numpy as np
import pytest
from _tolerances import FLOAT32_EPS, max_abs

from clsas import kernelmath
from clsas.backend import check_precision


@pytest.mark.parametrize("precision", ["single", "double"])
def test_rotate_phase_matches_numpy(backend, precision, rng):
    n = 20_000
    x = (rng.standard_normal(n) + 1j * rng.standard_normal(n)).astype(np.complex64)
    cycles = rng.uniform(-1e4, 1e4, n)
    if precision == "single":
        # the float kernel sees cycles rounded to float32; hold it to NumPy on the same input
        cycles = cycles.astype(np.float32)
    got = kernelmath.rotate_phase(x, cycles, backend=backend, precision=precision)
    expected = x.astype(np.complex128) * np.exp(2j * np.pi * cycles.astype(np.float64))
    # float: reduction to the fractional part is exact, sinpi/cospi and the complex multiply
    # cost a few ulp of |x| (|x| < 6 here); double: ~1e-15 relative, plus the 1e4-cycle
    # argument's own rounding in the NumPy expectation (1e4 * 2^-52 cycles).
    tol = 16 * FLOAT32_EPS * np.abs(x).max() if precision == "single" else 1e-10
    assert max_abs(got, expected) < tol
    if check_precision(precision) and backend == "opencl":
        assert got.dtype == np.complex128


def test_rotate_phase_quarter_turns(backend):
    got = kernelmath.rotate_phase(np.ones(5, np.complex64), np.array([0, 0.25, 0.5, -0.25, 1000.75]),
                                  backend=backend)
    np.testing.assert_allclose(got, [1, 1j, -1, -1j, -1j], atol=1e-6)


@pytest.mark.parametrize("taps,beta", [(8, 2.5), (16, 6.0)])
def test_kaiser_sinc_taps_match_numpy(backend, taps, beta, rng):
    offsets = np.concatenate([rng.uniform(-taps / 2 - 1, taps / 2 + 1, 5000), np.arange(-taps // 2, taps // 2 + 1)])
    got = kernelmath.kaiser_sinc_taps(offsets, taps / 2, beta, backend=backend)
    expected = kernelmath.kaiser_sinc_tap(offsets.astype(np.float32).astype(np.float64), taps / 2, beta)
    assert max_abs(got, expected) < 2e-6
    # interpolation taps: 1 at the sample itself, 0 at the other integers, 0 outside the support
    at_integers = kernelmath.kaiser_sinc_taps(np.arange(-taps // 2, taps // 2 + 1).astype(float), taps / 2,
                                              beta, backend=backend)
    expected_int = (np.arange(-taps // 2, taps // 2 + 1) == 0).astype(float)
    np.testing.assert_allclose(at_integers, expected_int, atol=1e-6)


def test_kaiser_window_is_numpys_kaiser():
    # at integer offsets k + 1/2 the tap is sinc * np.kaiser evaluated at the same point
    half = 4
    x = np.linspace(-half + 1e-9, half - 1e-9, 9)
    window = np.i0(5.0 * np.sqrt(1 - (x / half) ** 2)) / np.i0(5.0)
    np.testing.assert_allclose(kernelmath.kaiser_sinc_tap(x, half, 5.0), np.sinc(x) * window, rtol=1e-12)


@pytest.mark.parametrize("kwargs,match", [
    ({"half_width": 0.0, "beta": 2.0}, "half_width"),
    ({"half_width": 4.0, "beta": -1.0}, "beta"),
    ({"half_width": 4.0, "beta": np.nan}, "beta"),
])
def test_kaiser_taps_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        kernelmath.kaiser_sinc_taps(np.zeros(3), backend="numpy", **kwargs)


def test_rotate_phase_bad_shapes():
    with pytest.raises(ValueError, match="equal length"):
        kernelmath.rotate_phase(np.ones(3), np.ones(4), backend="numpy")


def test_expj_fraction_polynomial(backend, rng):
    r = np.concatenate([rng.uniform(-0.999, 0.999, 50_000), [-0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75]])
    r32 = r.astype(np.float32).astype(np.float64)  # the kernel's input
    got = kernelmath.expj_fractions(r32, backend=backend)
    # the polynomial's own error is < 1.4e-8 (common.h); float32 arithmetic adds up to ~6e-7
    # (s = pi r is rounded to 1.2e-7 rad and the double-angle step doubles it)
    assert max_abs(got, np.exp(2j * np.pi * r32)) < 1e-6


def test_expj_fraction_rejects_unreduced_phases():
    with pytest.raises(ValueError, match="cycles"):
        kernelmath.expj_fractions(np.array([1.5]), backend="numpy")
