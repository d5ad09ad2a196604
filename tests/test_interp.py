"""The interpolators of clsas.interp: the OpenCL row kernel against its NumPy reference and the
shared tap table."""

from __future__ import annotations

import numpy as np
import pytest
from _band_limited import band_limited
from _tolerances import rel_l2

from clsas.interp import TAP_ROWS, resample, tap_table


def test_tap_rows_sum_to_one_and_interpolate_at_zero_offset():
    for taps in (8, 16):
        for window in ("kaiser", "knab"):
            table = tap_table(taps, window)
            assert table.shape == (TAP_ROWS, taps)
            assert np.allclose(table.sum(axis=1), 1.0)
            assert np.allclose(table[0], np.eye(taps)[taps // 2 - 1], atol=1e-12)


@pytest.mark.parametrize("interp", ["linear", "sinc8", "sinc16"])
@pytest.mark.parametrize("shared", [True, False])
def test_resample_kernel_matches_reference(opencl_device, rng, interp, shared):
    """Explicit positions (per row, or one row shared by all): random ones past both edges,
    exact integers, and a row length (500) that ends inside a work-item's 64 outputs."""
    src = band_limited(rng, 40, 512)
    idx = rng.uniform(-6.0, 518.0, 500 if shared else (40, 500))
    idx[..., :8] = np.arange(8.0) - 2  # integers: the edge test must agree exactly
    ref = resample(src, idx, interp, backend="numpy")
    out = resample(src, idx, interp, backend="opencl")
    assert out.shape == ref.shape == (40, 500)
    assert np.array_equal(out == 0, ref == 0)
    assert np.count_nonzero(ref) > 0.9 * ref.size
    assert rel_l2(out, ref) < 1e-4


@pytest.mark.parametrize("n_rows", [1, 13])
def test_row_kernel_rows_in_whole_work_groups(opencl_device, rng, n_rows):
    """The row kernels launch in fixed work-groups (the rows padded to whole groups, compiled once
    whatever the shape): a row count that is not a multiple of the group gives exactly the rows
    that a larger call gives, and nothing is written past the last row."""
    src = band_limited(rng, 16, 256)
    idx = rng.uniform(-2.0, 258.0, (16, 70))
    whole = resample(src, idx, "sinc8", backend="opencl")
    part = resample(src[:n_rows], idx[:n_rows], "sinc8", backend="opencl")
    assert part.shape == (n_rows, 70)
    assert np.array_equal(part, whole[:n_rows])


def test_resample_bad_input(rng):
    src = band_limited(rng, 4, 64)
    with pytest.raises(ValueError, match="idx"):
        resample(src, np.zeros((3, 10)), backend="numpy")
    with pytest.raises(ValueError, match="idx"):
        resample(src, np.array([1.0, np.nan]), backend="numpy")
    with pytest.raises(ValueError, match="src"):
        resample(src[0], np.zeros(3), backend="numpy")
    with pytest.raises(ValueError, match="interp"):
        resample(src, np.zeros(3), "cubic", backend="numpy")
